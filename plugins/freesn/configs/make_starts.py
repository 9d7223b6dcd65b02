"""Write the start configurations of the FreeSN locomotion scenarios (issue 13).

Each start is a library configuration as a "newly constructed system" would present
it (FreeSN paper, section 6.3, Fig. 15(a)): every module renamed (a random permutation
onto the system's own ids), the whole turned about the vertical by a random yaw, and
every connection vector tilted by a few degrees. Positions are dropped (the world
places the modules from the vectors). Reproducible::

    python plugins/freesn/configs/make_starts.py     # seed SEED, rewrites the files below
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from msrr.core.alignment import rot_z
from msrr.core.configuration import Configuration
from msrr.core.io import load_configuration, save_configuration

HERE = Path(__file__).resolve().parent
SEED = 13
PERTURB = np.radians(3.0)
"""Standard deviation of each vector's tilt [rad]."""

STARTS = {
    "s4n5-star-start": ("S4N5-1.1", "S4N5 star lying flat (library S4N5-1.1) as a new system: "
                        "relabelled, yawed, perturbed"),
    "s4n5-chain-start": ("S4N5-2.1", "S4N5 chain lying flat (library S4N5-2.1) as a new "
                         "system: relabelled, yawed, perturbed"),
    "s12n6-octahedron-start": ("S12N6-1.1", "S12N6 octahedron (library S12N6-1.1, Fig. 22(a)) "
                               "as a new system: relabelled, yawed, perturbed"),
}
"""Start file name -> (library configuration, description)."""


def new_system(config: Configuration, rng: np.random.Generator, name: str,
               description: str) -> Configuration:
    """``config`` renamed, yawed by a uniform random angle and each vector tilted."""
    nodes = [v for v in config.vertices() if not config.is_virtual(v)]
    struts = config.edge_ids()
    node_ids = {v: f"n{i + 1}" for v, i in zip(nodes, rng.permutation(len(nodes)), strict=True)}
    strut_ids = {e: f"s{i + 1}" for e, i in zip(struts, rng.permutation(len(struts)),
                                                 strict=True)}
    yaw = rot_z(float(rng.uniform(-np.pi, np.pi)))
    out = Configuration(config.robot, name=name, description=description)
    for v in sorted(nodes, key=node_ids.get):
        out.add_module(node_ids[v], "node")
    for e in sorted(struts, key=strut_ids.get):
        edge = config.edge(e)
        ends = []
        for v in (edge.source, edge.target):
            if config.is_virtual(v):
                v = f"{strut_ids[e]}:{'a' if v == edge.source else 'b'}"
                out.add_virtual(v)
                ends.append(v)
            else:
                ends.append(node_ids[v])
        z = yaw @ edge.z
        tilt = rng.normal(scale=PERTURB, size=3)
        z = Rotation.from_rotvec(tilt - np.dot(tilt, z) * z).apply(z)
        out.connect(ends[0], ends[1], id=strut_ids[e], kind=edge.kind, z=z / np.linalg.norm(z))
    return out


def main() -> None:
    rng = np.random.default_rng(SEED)
    for name, (library_id, description) in STARTS.items():
        config = load_configuration(HERE / "library" / f"{library_id}.json")
        save_configuration(new_system(config, rng, name, description), HERE / f"{name}.json")
        print(f"wrote {name}.json from {library_id} (seed {SEED})")


if __name__ == "__main__":
    main()
