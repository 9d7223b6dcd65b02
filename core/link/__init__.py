"""The module link: protocol, security, the ``link`` driver and the module emulator.

* :mod:`.protocol` -- frames (a 9-byte header, the payload sealed by ChaCha20-Poly1305,
  the COMMAND frame signed), their age check (:class:`Freshness`) and payload layouts;
* :mod:`.keys` -- the key schedule: module keys from the site key (HKDF), session keys
  from an X25519 handshake, the run's group key and signing key;
* :mod:`.codec` -- the payloads' CBOR (``cbor2``, deterministic), records by id;
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
    from .codec import Codec, CodecError, RecordSpec, RecordTable
    from .driver import LinkDriver, LinkDriverFactory
    from .emulator import LINK_FAULT_KINDS, Emulator, parse_link_faults
    from .keys import module_key
    from .module import DEFAULT_WATCHDOG_PERIODS, ModuleLink, WatchdogTrip
    from .protocol import VERSION, FrameType, Freshness, Header, LinkStats, Refused
    from .system import (
               GroupAddress,
               KeyRef,
               ModuleEntry,
               RecordEntry,
               SystemFile,
               load_key,
               load_system,
               new_key,
               write_key,
               write_system,
    )

_EXPORTS = {  # name -> submodule that defines it
    **dict.fromkeys(("Codec", "CodecError", "RecordSpec", "RecordTable"), "codec"),
    **dict.fromkeys(("LinkDriver", "LinkDriverFactory"), "driver"),
    **dict.fromkeys(("LINK_FAULT_KINDS", "Emulator", "parse_link_faults"), "emulator"),
    "module_key": "keys",
    **dict.fromkeys(("DEFAULT_WATCHDOG_PERIODS", "ModuleLink", "WatchdogTrip"), "module"),
    **dict.fromkeys(("VERSION", "FrameType", "Freshness", "Header", "LinkStats", "Refused"),
                    "protocol"),
    **dict.fromkeys(("GroupAddress", "KeyRef", "ModuleEntry", "RecordEntry", "SystemFile",
                     "load_key", "load_system", "new_key", "write_key", "write_system"),
                    "system"),
}

__all__ = ["DEFAULT_WATCHDOG_PERIODS", "LINK_FAULT_KINDS", "VERSION", "Codec", "CodecError",
           "Emulator", "FrameType", "Freshness", "GroupAddress", "Header", "KeyRef",
           "LinkDriver", "LinkDriverFactory", "LinkStats", "ModuleEntry", "ModuleLink",
           "RecordEntry", "RecordSpec", "RecordTable", "Refused", "SystemFile", "WatchdogTrip",
           "load_key", "load_system", "module_key", "new_key", "parse_link_faults",
           "write_key", "write_system"]

__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
