"""Who may use the SQL endpoint: a users file of bcrypt password hashes checked with HTTP Basic
authentication, and the rules for where the server may listen.

The users file has one `user:bcrypt-hash` per line (blank lines and `#` comments allowed); make a
hash with `python -c "import bcrypt; print(bcrypt.hashpw(b'secret', bcrypt.gensalt()).decode())"`.
A successful check is remembered (as a SHA-256 digest of user and password) so that the bcrypt
cost is paid once per client, not on every page request. An unknown user costs a bcrypt check too
(against a dummy hash), so that answer times do not tell which users exist; a password over 72
bytes (bcrypt's limit) never matches. `LoginFailures` makes a client wait after repeated failures.
"""

from __future__ import annotations

import base64
import binascii
import hashlib
import ipaddress
import math
import secrets
import threading
import time
from collections import OrderedDict
from pathlib import Path

import bcrypt

#: Remembered successful logins.
CACHE_SIZE = 1024
_BCRYPT_PREFIXES = ("$2a$", "$2b$", "$2y$")
#: The longest password bcrypt checks (bcrypt 5 refuses longer ones; older versions truncated them).
MAX_PASSWORD_BYTES = 72


class UsersFileError(ValueError):
    """A users file that cannot be read; the message names the file and line."""


class Users:
    """The users who may log in, with their bcrypt password hashes."""

    def __init__(self, hashes: dict[str, bytes]):
        self._hashes = hashes
        cost = max(int(hashed[4:6]) for hashed in hashes.values())  # $2b$12$...: the slowest stored cost
        self._dummy = bcrypt.hashpw(secrets.token_bytes(16), bcrypt.gensalt(cost))
        self._verified: OrderedDict[bytes, None] = OrderedDict()
        self._lock = threading.Lock()

    @classmethod
    def load(cls, path: Path) -> Users:
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
        """Whether `password` is `user`'s (bcrypt: slow the first time, remembered after; as slow
        for an unknown user)."""
        key = self._key(user, password)
        with self._lock:
            if key is not None and key in self._verified:
                self._verified.move_to_end(key)
                return True
        secret = password.encode("utf-8", "surrogatepass")
        hashed = self._hashes.get(user, self._dummy)
        matches = bcrypt.checkpw(secret[:MAX_PASSWORD_BYTES], hashed)  # the same work for any name or length
        if key is None or not matches or len(secret) > MAX_PASSWORD_BYTES:
            return False
        with self._lock:
            self._verified[key] = None
            if len(self._verified) > CACHE_SIZE:
                self._verified.popitem(last=False)
        return True


class LoginFailures:
    """Failed logins per client address and user name, per client address (any user name) and per
    user name (any address, so that guesses spread over many addresses count too): after
    FREE_FAILURES in a row for one user from one address (CLIENT_FREE_FAILURES over all user names
    from one address, USER_FREE_FAILURES for one user from all addresses), the client must wait 1 s
    after its last attempt, then 2, 4 ... up to MAX_WAIT seconds, before it may try again. A login
    that succeeds takes its attempt back; counts are forgotten FORGET seconds after their last
    attempt. Attempts count when they start, so parallel guesses count too."""

    FREE_FAILURES = 5
    CLIENT_FREE_FAILURES = 20
    USER_FREE_FAILURES = 10
    MAX_WAIT = 60
    FORGET = 900
    MAX_KEYS = 10_000  # the least recently tried are forgotten beyond this

    def __init__(self) -> None:
        self._failures: OrderedDict[tuple[str | None, str | None], tuple[int, float]] = OrderedDict()
        self._lock = threading.Lock()

    def wait(self, client: str, user: str) -> int:
        """Seconds the client must still wait before trying `user` again (0: it may try now)."""
        now = time.monotonic()
        with self._lock:
            return max(
                self._wait((client, user), self.FREE_FAILURES, now),
                self._wait((client, None), self.CLIENT_FREE_FAILURES, now),
                self._wait((None, user), self.USER_FREE_FAILURES, now),
            )

    def _wait(self, key: tuple[str | None, str | None], free: int, now: float) -> int:
        count, last = self._failures.get(key, (0, 0.0))
        if count < free or now - last > self.FORGET:
            return 0
        return math.ceil(max(0.0, last + min(2 ** (count - free), self.MAX_WAIT) - now))

    def attempt(self, client: str, user: str) -> None:
        """An attempt starts: it counts as a failure until it `succeeded`."""
        now = time.monotonic()
        with self._lock:
            for key in ((client, user), (client, None), (None, user)):
                count, last = self._failures.pop(key, (0, 0.0))
                self._failures[key] = (1 if now - last > self.FORGET else count + 1, now)
            while len(self._failures) > self.MAX_KEYS:
                self._failures.popitem(last=False)

    def succeeded(self, client: str, user: str) -> None:
        with self._lock:
            self._failures.pop((client, user), None)
            self._failures.pop((None, user), None)
            count, last = self._failures.get((client, None), (1, 0.0))
            self._failures[(client, None)] = (count - 1, last)


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
        raise ValueError(
            f"refusing to serve on {host} without authentication: pass --users FILE and "
            "--tls-cert/--tls-key (or listen on 127.0.0.1)"
        )
    if not tls:
        raise ValueError(
            f"refusing to serve on {host} without TLS: passwords would cross the network in clear "
            "text; pass --tls-cert and --tls-key"
        )
