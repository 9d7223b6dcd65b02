"""What a robot declares about its data on the module link, from its own package.

Two things only the robot knows, which make its frames smaller:

* **vectors**: joint names ``N`` whose joints ``N_x``, ``N_y``, ``N_z`` carry a unit
  vector (FreeSN's connection vectors ``a.dir_x``...): each travels as one 4-byte
  direction instead of three floats;
* **pose_every**: how often a report carries the module's pose. The pose is the one
  thing in a report a robot may only watch (timeline, distance, judge) rather than close
  a loop on; a robot whose controllers read only the modules' sensor data (FreeSN: real
  modules measure no world pose at all) declares 2, one in every second report at most.
  The default 1 keeps it in every report that changed it, as pose-feedback controllers
  (the generic runtime's) need.

The plugin declares them when its command module is imported::

    from msrr.core.link.declarations import declare_link
    declare_link("freesn", vectors=("a.dir", "a.fwd", "b.dir", "b.fwd"), pose_every=2)

``platform emulate`` writes the declaration into the systems file (``vectors``,
``pose_every``), and the host and the modules follow the systems file, the contract a
lab's firmware shares (``docs/protocol.md``, "Encoding" and "REPORT"). The core imports
no plugin: the declaration comes from the plugin.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

__all__ = ["LinkDeclaration", "declare_link", "declared"]


@dataclass(frozen=True)
class LinkDeclaration:
    """A robot's declaration (module doc)."""

    vectors: tuple[str, ...] = ()
    pose_every: int = 1


_DECLARED: dict[str, LinkDeclaration] = {}


def declare_link(robot: str, *, vectors: Iterable[str] = (), pose_every: int = 1) -> None:
    """Declare ``robot``'s unit-vector joints and pose spacing (replacing an earlier
    declaration).

    Raises:
        ValueError: ``pose_every`` below 1 or above 10.
    """
    if isinstance(pose_every, bool) or not isinstance(pose_every, int) or \
            not 1 <= pose_every <= 10:
        raise ValueError(f"pose_every must be an integer in [1, 10], got {pose_every!r}")
    _DECLARED[robot] = LinkDeclaration(tuple(dict.fromkeys(str(n) for n in vectors)),
                                       pose_every)


def declared(robot: str) -> LinkDeclaration:
    """What ``robot`` declared (nothing: the defaults)."""
    return _DECLARED.get(robot, LinkDeclaration())
