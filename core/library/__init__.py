"""The behavior library (FreeSN paper, section 6): design, creation, storage, retrieval.

* :mod:`.model` -- sub-libraries, groups, configurations, behaviors, action edges (6.1);
* :mod:`.sources` -- designed groups and recorded sequences, the build inputs (6.2);
* :mod:`.build` -- automatic creation: match, remap, merge, add edges (6.2, Fig. 14);
* :mod:`.storage` -- one JSON file per library, validated, written atomically;
* :mod:`.retrieve` -- match, shortest action path, remap to system ids (6.3, Fig. 15).
"""

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
from .retrieve import Retrieval, RetrievedStep, retrieve, shortest_path
from .sources import LibrarySources, load_sources
from .storage import LIBRARY_SCHEMA_VERSION, LibraryFile, dump_library, load_library, save_library

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
    "retrieve",
    "save_library",
    "shortest_path",
]
