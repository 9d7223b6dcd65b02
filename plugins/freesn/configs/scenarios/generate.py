"""Write the start configurations of the FreeSN scenarios: "newly built" systems.

Each start is a library configuration as a newly constructed system would report it
(FreeSN paper, section 7): modules renamed in a random order, the whole turned by a
random yaw, every connection vector tilted by a few degrees
(:func:`msrr.core.random_configurations.newly_built`), so a scenario run begins with
recognition and matching, never with the library's own ids. Seeded: running this again
writes the same files (``tests/plugins/freesn/test_freesn_scenarios.py`` checks it)::

    python plugins/freesn/configs/scenarios/generate.py
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from msrr.core.io import configuration_to_model
from msrr.core.plugins import load_configuration
from msrr.core.random_configurations import newly_built

HERE = Path(__file__).resolve().parent
LIBRARY = HERE.parent / "library"

STARTS = {
    # file name: (library configuration, seed, tilt std [deg], description)
    "fig20-start": ("S6N3-1.1", 20, 4.0,
                    "Fig. 20(a) as built: a triangle with three legs, relabelled, yawed, tilted"),
    "fig21-start": ("S12N6-2.1", 21, 4.0,
                    "Fig. 21(a) as built: a hexagonal star, relabelled, yawed, tilted"),
    "fig22-start": ("S12N6-1.1", 22, 4.0,
                    "Fig. 22(a) as built: an octahedron, relabelled, yawed, tilted"),
    "fig18-node-wheels-start": ("S4N5-1.1", 181, 3.0, "Fig. 18(a) as built: S4N5 star lying "
                                "flat, relabelled, yawed, tilted"),
    "fig18-strut-wheels-start": ("S4N1-1.2", 184, 3.0, "Fig. 18(d) as built: S4N1 standing on "
                                 "its leaf struts' wheels (x: their axles tangential), "
                                 "relabelled, yawed, tilted"),
    "fig18-struts-as-wheels-start": ("S4N1-1.3", 187, 3.0, "Fig. 18(g) as built: S4N1 with its "
                                     "leaf struts low on the floor, relabelled, yawed, tilted"),
    "fig19-crawl-start": ("S4N5-1.1", 191, 3.0, "Fig. 19(f) as built: S4N5 star lying flat, "
                          "relabelled, yawed, tilted"),
    "fig19-squirm-start": ("S4N5-2.1", 193, 3.0, "Fig. 19(a) as built: S4N5 chain lying flat "
                           "(end struts splayed), relabelled, yawed, tilted"),
    "fig19-crawl-s12n6-start": ("S12N6-8.1", 196, 3.0, "Fig. 19(k) as built: the S12N6 "
                                "quadruped standing in its first crawl stance, relabelled, "
                                "yawed, tilted (n0 a body node)"),
}
"""The start files and how each is made."""


def start_document(name: str) -> str:
    """The JSON text of start file ``name`` (node positions left out: the simulator lays
    the system out from its vectors)."""
    source, seed, tilt, description = STARTS[name]
    config = newly_built(load_configuration(LIBRARY / f"{source}.json"),
                         np.random.default_rng(seed), noise=math.radians(tilt), name=name)
    model = configuration_to_model(config)
    model.description = description
    for module in model.modules:
        module.position = None
    return model.model_dump_json(indent=2, exclude_none=True) + "\n"


def main() -> None:
    for name in STARTS:
        path = HERE / f"{name}.json"
        path.write_text(start_document(name))
        print(f"wrote {path}")


if __name__ == "__main__":
    main()
