"""The link's key schedule (``docs/protocol.md``, "Keys"), all from ``cryptography``.

* **Site key** ``S``: 32 random bytes, held by the host (the systems file refers to it);
  never on a module.
* **Module key** ``K_m = HKDF-SHA256(S, salt="msrr link 2 module", info=system || number)``
  (RFC 5869): flashed into module ``m`` alone. It authenticates the handshake only; a
  module's key gives nothing about another module's (HKDF outputs are independent).
* **Session keys**: each handshake is an ephemeral X25519 exchange (RFC 7748) whose two
  public keys travel in frames sealed with ``K_m``;
  ``HKDF-SHA256(shared, salt=K_m, info="msrr link 2 session" || host public || module
  public || system || number)`` gives 64 bytes: the host -> module key, then the module
  -> host key. Recorded traffic stays sealed even if ``K_m`` leaks later (forward secrecy).
* **Group key and command signature**: per host run the host draws a group key (the
  one command frame of every tick is sealed with it, so an outsider cannot read it)
  and an Ed25519 key pair (RFC 8032) whose signature on that frame proves the host
  sent it, so a module, which knows the group key, still cannot command another
  module. Both reach each module in its SETUP frame, under its session key.

Every AEAD is ChaCha20-Poly1305 (RFC 8439) through :class:`Aead`.
"""

from __future__ import annotations

import secrets
import struct
from dataclasses import dataclass

from cryptography.exceptions import InvalidSignature, InvalidTag
from cryptography.hazmat.primitives import hashes
from cryptography.hazmat.primitives.asymmetric.ed25519 import Ed25519PrivateKey, Ed25519PublicKey
from cryptography.hazmat.primitives.asymmetric.x25519 import X25519PrivateKey, X25519PublicKey
from cryptography.hazmat.primitives.ciphers.aead import ChaCha20Poly1305
from cryptography.hazmat.primitives.kdf.hkdf import HKDF

__all__ = ["KEY_BYTES", "PUBLIC_BYTES", "Aead", "Ephemeral", "SessionKeys", "Signer", "Verifier",
           "module_key", "random_key", "session_keys"]

KEY_BYTES = 32
PUBLIC_BYTES = 32
_MODULE_SALT = b"msrr link 2 module"
_SESSION_INFO = b"msrr link 2 session"


def random_key() -> bytes:
    """32 random bytes (a site key, a group key)."""
    return secrets.token_bytes(KEY_BYTES)


def module_key(site_key: bytes, system: int, number: int) -> bytes:
    """The key of module ``number`` of ``system``, derived from the site key (HKDF)."""
    return HKDF(algorithm=hashes.SHA256(), length=KEY_BYTES, salt=_MODULE_SALT,
                info=struct.pack("<IH", system, number)).derive(site_key)


class Aead:
    """ChaCha20-Poly1305 under one key; ``None`` from :meth:`open` when the tag is wrong."""

    __slots__ = ("_cipher",)

    def __init__(self, key: bytes):
        self._cipher = ChaCha20Poly1305(key)

    def __repr__(self) -> str:
        return "Aead(<key withheld>)"

    def seal(self, nonce: bytes, plaintext: bytes, associated: bytes) -> bytes:
        return self._cipher.encrypt(nonce, plaintext, associated)

    def open(self, nonce: bytes, sealed: bytes, associated: bytes) -> bytes | None:
        try:
            return self._cipher.decrypt(nonce, sealed, associated)
        except InvalidTag:
            return None


@dataclass(frozen=True, repr=False)
class SessionKeys:
    """The two directions of one session (never printed)."""

    to_module: Aead
    to_host: Aead

    def __repr__(self) -> str:
        return "SessionKeys(<withheld>)"


def session_keys(shared: bytes, key: bytes, host_public: bytes, module_public: bytes,
                 system: int, number: int) -> SessionKeys:
    """Both keys of a session from the X25519 secret ``shared`` (module doc)."""
    info = _SESSION_INFO + host_public + module_public + struct.pack("<IH", system, number)
    okm = HKDF(algorithm=hashes.SHA256(), length=2 * KEY_BYTES, salt=key,
               info=info).derive(shared)
    return SessionKeys(Aead(okm[:KEY_BYTES]), Aead(okm[KEY_BYTES:]))


class Ephemeral:
    """One side's X25519 key pair of one handshake."""

    __slots__ = ("_private", "public")

    def __init__(self) -> None:
        self._private = X25519PrivateKey.generate()
        self.public = self._private.public_key().public_bytes_raw()

    def __repr__(self) -> str:
        return f"Ephemeral(public={self.public[:4].hex()}...)"

    def shared(self, peer_public: bytes) -> bytes | None:
        """The shared secret with ``peer_public``; ``None`` for a malformed or low-order
        public key (RFC 7748 section 6.1: an all-zero result)."""
        try:
            return self._private.exchange(X25519PublicKey.from_public_bytes(peer_public))
        except ValueError:
            return None


class Signer:
    """The host's Ed25519 key of one run (signs the command frame of every tick)."""

    __slots__ = ("_private", "public")

    def __init__(self) -> None:
        self._private = Ed25519PrivateKey.generate()
        self.public = self._private.public_key().public_bytes_raw()

    def __repr__(self) -> str:
        return "Signer(<key withheld>)"

    def sign(self, data: bytes) -> bytes:
        return self._private.sign(data)


class Verifier:
    """A module's check of the host's signature; ``None`` from the constructor's caller
    when the public key is malformed (:meth:`parse`)."""

    __slots__ = ("_public",)

    def __init__(self, public: Ed25519PublicKey):
        self._public = public

    @classmethod
    def parse(cls, public: bytes) -> Verifier | None:
        try:
            return cls(Ed25519PublicKey.from_public_bytes(public))
        except ValueError:
            return None

    def verify(self, signature: bytes, data: bytes) -> bool:
        try:
            self._public.verify(signature, data)
        except InvalidSignature:
            return False
        return True
