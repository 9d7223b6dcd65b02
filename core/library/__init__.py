"""The behavior library (FreeSN paper, section 6): design, creation, storage, retrieval.

* :mod:`.model` -- sub-libraries, groups, configurations, behaviors, action edges (6.1);
* :mod:`.sources` -- designed groups and recorded sequences, the build inputs (6.2);
* :mod:`.build` -- automatic creation: match, remap, merge, add edges (6.2, Fig. 14);
* :mod:`.storage` -- one JSON file per library, validated, written atomically;
* :mod:`.retrieve` -- match, shortest action path, remap to system ids (6.3, Fig. 15).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ..lazy import lazy_exports

if TYPE_CHECKING:
    from ..mapping import ModuleMap
    from .build import DEFAULT_MERGE_THRESHOLD, build_library, build_steps
    from .model import (
        ActionEdge,
        Behavior,
        CommandGain,
        Group,
        Library,
        LibraryConfiguration,
        LibraryError,
        RetrievalError,
        SubLibrary,
        TreeRef,
    )
    from .retrieve import Retrieval, RetrievedStep, shortest_path
    from .sources import LibrarySources, load_sources
    from .storage import (
        LIBRARY_SCHEMA_VERSION,
        LibraryFile,
        dump_library,
        load_library,
        save_library,
    )

_EXPORTS = {  # name -> submodule that defines it
    "ModuleMap": "..mapping",
    **dict.fromkeys(("DEFAULT_MERGE_THRESHOLD", "build_library", "build_steps"), "build"),
    **dict.fromkeys(("ActionEdge", "Behavior", "CommandGain", "Group", "Library",
                     "LibraryConfiguration", "LibraryError", "RetrievalError", "SubLibrary",
                     "TreeRef"), "model"),
    # ``retrieve`` (the function) is imported from ``msrr.core.library.retrieve``: the
    # submodule of that name would shadow it here once imported
    **dict.fromkeys(("Retrieval", "RetrievedStep", "shortest_path"), "retrieve"),
    **dict.fromkeys(("LibrarySources", "load_sources"), "sources"),
    **dict.fromkeys(("LIBRARY_SCHEMA_VERSION", "LibraryFile", "dump_library", "load_library",
                     "save_library"), "storage"),
}

__all__ = [
    "DEFAULT_MERGE_THRESHOLD",
    "LIBRARY_SCHEMA_VERSION",
    "ActionEdge",
    "Behavior",
    "CommandGain",
    "Group",
    "Library",
    "LibraryConfiguration",
    "LibraryError",
    "LibraryFile",
    "LibrarySources",
    "ModuleMap",
    "RetrievalError",
    "Retrieval",
    "RetrievedStep",
    "SubLibrary",
    "TreeRef",
    "build_library",
    "build_steps",
    "dump_library",
    "load_library",
    "load_sources",
    "save_library",
    "shortest_path",
]

__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
