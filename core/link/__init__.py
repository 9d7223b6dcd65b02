"""The module link: protocol, security, the ``link`` driver and the module emulator.

* :mod:`.protocol` -- frames (fixed little-endian header, CBOR payload, HMAC-SHA256
  tag), the receive checks (:class:`Endpoint`) and the command payload;
* :mod:`.cbor` -- the CBOR subset of the payloads (no dependency);
* :mod:`.system` -- the systems file and its key reference;
* :mod:`.module` -- a module's end (what firmware implements), with its watchdog;
* :mod:`.driver` -- the host's end, the ``link`` :class:`~msrr.core.driver.Driver`;
* :mod:`.emulator` -- emulated modules backed by a robot's simulator.

``docs/protocol.md`` specifies the protocol, ``docs/hardware.md`` how to use it.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ..lazy import lazy_exports

if TYPE_CHECKING:
    from .driver import LinkDriver, LinkDriverFactory
    from .emulator import LINK_FAULT_KINDS, Emulator, parse_link_faults
    from .module import DEFAULT_WATCHDOG_PERIODS, ModuleLink, WatchdogTrip
    from .protocol import (
               VERSION,
               Endpoint,
               Frame,
               FrameType,
               LinkStats,
               Refused,
               decode_frame,
               encode_frame,
    )
    from .system import (
               KeyRef,
               ModuleEntry,
               SystemFile,
               load_key,
               load_system,
               new_key,
               write_key,
               write_system,
    )

_EXPORTS = {  # name -> submodule that defines it
    **dict.fromkeys(("LinkDriver", "LinkDriverFactory"), "driver"),
    **dict.fromkeys(("LINK_FAULT_KINDS", "Emulator", "parse_link_faults"), "emulator"),
    **dict.fromkeys(("DEFAULT_WATCHDOG_PERIODS", "ModuleLink", "WatchdogTrip"), "module"),
    **dict.fromkeys(("VERSION", "Endpoint", "Frame", "FrameType", "LinkStats", "Refused",
                     "decode_frame", "encode_frame"), "protocol"),
    **dict.fromkeys(("KeyRef", "ModuleEntry", "SystemFile", "load_key", "load_system",
                     "new_key", "write_key", "write_system"), "system"),
}

__all__ = ["DEFAULT_WATCHDOG_PERIODS", "LINK_FAULT_KINDS", "VERSION", "Emulator", "Endpoint", "Frame",
           "FrameType", "KeyRef", "LinkDriver", "LinkDriverFactory", "LinkStats", "ModuleEntry",
           "ModuleLink", "Refused", "SystemFile", "WatchdogTrip", "decode_frame", "encode_frame",
           "load_key", "load_system", "new_key", "parse_link_faults",
           "write_key", "write_system"]

__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
