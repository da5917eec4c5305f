"""Who may use the SQL endpoint: a users file of bcrypt password hashes checked with HTTP Basic
authentication, and the rules for where the server may listen.

The users file has one `user:bcrypt-hash` per line (blank lines and `#` comments allowed); make a
hash with `python -c "import bcrypt; print(bcrypt.hashpw(b'secret', bcrypt.gensalt()).decode())"`.
A successful check is remembered (as a SHA-256 digest of user and password) so that the bcrypt
cost is paid once per client, not on every page request.
"""
from __future__ import annotations

import base64
import binascii
import hashlib
import ipaddress
import threading
from collections import OrderedDict
from pathlib import Path

import bcrypt

#: Remembered successful logins.
CACHE_SIZE = 1024
_BCRYPT_PREFIXES = ("$2a$", "$2b$", "$2y$")


class UsersFileError(ValueError):
    """A users file that cannot be read; the message names the file and line."""


class Users:
    """The users who may log in, with their bcrypt password hashes."""

    def __init__(self, hashes: dict[str, bytes]):
        self._hashes = hashes
        self._verified: OrderedDict[bytes, None] = OrderedDict()
        self._lock = threading.Lock()

    @classmethod
    def load(cls, path: Path) -> "Users":
        """Read a users file (`user:bcrypt-hash` lines); UsersFileError says where it is wrong."""
        path = Path(path)
        try:
            text = path.read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError) as error:
            raise UsersFileError(f"users file {str(path)!r} cannot be read: {error}") from None
        hashes: dict[str, bytes] = {}
        for number, line in enumerate(text.splitlines(), 1):
            line = line.strip()
            if not line or line.startswith("#"):
                continue
            user, colon, hashed = line.partition(":")
            where = f"{path}:{number}"
            if not colon or not user.strip():
                raise UsersFileError(f"{where}: expected 'user:bcrypt-hash'")
            user, hashed = user.strip(), hashed.strip()
            if not hashed.startswith(_BCRYPT_PREFIXES) or len(hashed) != 60:
                raise UsersFileError(f"{where}: the password of {user!r} is not a bcrypt hash ($2b$..., 60 characters)")
            if user in hashes:
                raise UsersFileError(f"{where}: user {user!r} is listed twice")
            hashes[user] = hashed.encode("ascii")
        if not hashes:
            raise UsersFileError(f"users file {str(path)!r} lists no user")
        return cls(hashes)

    def _key(self, user: str, password: str) -> bytes | None:
        hashed = self._hashes.get(user)
        if hashed is None:
            return None
        return hashlib.sha256(f"{user}\0{password}".encode("utf-8", "surrogatepass")).digest() + hashed

    def remembered(self, user: str, password: str) -> bool:
        """Whether this user and password were verified before (fast; no bcrypt)."""
        key = self._key(user, password)
        with self._lock:
            return key is not None and key in self._verified

    def verify(self, user: str, password: str) -> bool:
        """Whether `password` is `user`'s (bcrypt: slow the first time, remembered after)."""
        key = self._key(user, password)
        if key is None:
            return False
        with self._lock:
            if key in self._verified:
                self._verified.move_to_end(key)
                return True
        if not bcrypt.checkpw(password.encode("utf-8", "surrogatepass"), self._hashes[user]):
            return False
        with self._lock:
            self._verified[key] = None
            if len(self._verified) > CACHE_SIZE:
                self._verified.popitem(last=False)
        return True


def basic_credentials(header: str | None) -> tuple[str, str] | None:
    """(user, password) of an `Authorization: Basic ...` header, else None."""
    if not header:
        return None
    scheme, _, token = header.partition(" ")
    if scheme.lower() != "basic":
        return None
    try:
        user, colon, password = base64.b64decode(token.strip(), validate=True).decode("utf-8").partition(":")
    except (binascii.Error, UnicodeDecodeError):
        return None
    return (user, password) if colon else None


def is_loopback(host: str) -> bool:
    """Whether `host` (a name or address to listen on) only accepts connections from this machine."""
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host.strip("[]")).is_loopback
    except ValueError:
        return False


def check_listen(host: str, *, users: bool, tls: bool) -> None:
    """Refuse (ValueError) to listen beyond this machine without authentication over TLS: the
    trino client sends passwords only over https, and a lake open to the network needs both."""
    if is_loopback(host):
        return
    if not users:
        raise ValueError(f"refusing to serve on {host} without authentication: pass --users FILE and "
                         "--tls-cert/--tls-key (or listen on 127.0.0.1)")
    if not tls:
        raise ValueError(f"refusing to serve on {host} without TLS: passwords would cross the network in clear "
                         "text; pass --tls-cert and --tls-key")
