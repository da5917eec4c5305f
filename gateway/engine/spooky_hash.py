"""SpookyHash V2 as Trino computes it: io.airlift.slice.SpookyHashV2.hash64 (Bob Jenkins' SpookyV2
Hash64: the first 64 bits of Hash128 with both seeds `seed`), ported to Python integers mod 2**64."""

from __future__ import annotations

_MASK = (1 << 64) - 1
_MAGIC = 0xDEADBEEFDEADBEEF
_SHORT_LIMIT = 192  # messages shorter than this take the short path
_BLOCK = 96  # twelve 8-byte words a block on the long path

_SHORT_MIX = (50, 52, 30, 41, 54, 48, 38, 37, 62, 34, 5, 36)
_SHORT_END = (15, 52, 26, 51, 28, 9, 47, 54, 32, 25, 63)
_MIX = (11, 32, 43, 31, 17, 28, 39, 57, 55, 54, 22, 46)
_END_PARTIAL = (44, 15, 34, 21, 38, 33, 10, 13, 38, 53, 42, 54)


def _rotate(x: int, k: int) -> int:
    return ((x << k) | (x >> (64 - k))) & _MASK


def _words(data: bytes) -> list[int]:
    return [int.from_bytes(data[i : i + 8], "little") for i in range(0, len(data), 8)]


def _short_mix(h: list[int]) -> None:
    for i, k in enumerate(_SHORT_MIX):
        a, b, c = (2 + i) % 4, (3 + i) % 4, i % 4
        h[a] = (_rotate(h[a], k) + h[b]) & _MASK
        h[c] ^= h[a]


def _short(data: bytes, seed: int) -> int:
    h = [seed, seed, _MAGIC, _MAGIC]
    whole = len(data) // 32 * 32
    for w in (_words(data[i : i + 32]) for i in range(0, whole, 32)):
        h[2], h[3] = (h[2] + w[0]) & _MASK, (h[3] + w[1]) & _MASK
        _short_mix(h)
        h[0], h[1] = (h[0] + w[2]) & _MASK, (h[1] + w[3]) & _MASK
    tail = data[whole:]
    if len(tail) >= 16:
        w = _words(tail[:16])
        h[2], h[3] = (h[2] + w[0]) & _MASK, (h[3] + w[1]) & _MASK
        _short_mix(h)
        tail = tail[16:]
    h[3] = (h[3] + (len(data) << 56)) & _MASK
    if tail:
        h[2] = (h[2] + int.from_bytes(tail[:8], "little")) & _MASK
        h[3] = (h[3] + int.from_bytes(tail[8:], "little")) & _MASK
    else:
        h[2], h[3] = (h[2] + _MAGIC) & _MASK, (h[3] + _MAGIC) & _MASK
    for i, k in enumerate(_SHORT_END):
        a, b = (3 + i) % 4, (2 + i) % 4
        h[a] ^= h[b]
        h[b] = _rotate(h[b], k)
        h[a] = (h[a] + h[b]) & _MASK
    return h[0]


def _long(data: bytes, seed: int) -> int:
    h = [_MAGIC if i % 3 == 2 else seed for i in range(12)]
    whole = len(data) // _BLOCK * _BLOCK
    for start in range(0, whole, _BLOCK):
        for i, word in enumerate(_words(data[start : start + _BLOCK])):
            h[i] = (h[i] + word) & _MASK
            h[(i + 2) % 12] ^= h[(i + 10) % 12]
            h[(i + 11) % 12] ^= h[i]
            h[i] = _rotate(h[i], _MIX[i])
            h[(i + 11) % 12] = (h[(i + 11) % 12] + h[(i + 1) % 12]) & _MASK
    rest = data[whole:]
    last = bytearray(rest.ljust(_BLOCK, b"\0"))
    last[-1] = len(rest)  # the block's last byte holds the count of bytes it carries
    for i, word in enumerate(_words(bytes(last))):
        h[i] = (h[i] + word) & _MASK
    for _ in range(3):
        for i, k in enumerate(_END_PARTIAL):
            h[(i + 11) % 12] = (h[(i + 11) % 12] + h[(i + 1) % 12]) & _MASK
            h[(i + 2) % 12] ^= h[(i + 11) % 12]
            h[(i + 1) % 12] = _rotate(h[(i + 1) % 12], k)
    return h[0]


def hash64(data: bytes, seed: int = 0) -> int:
    """SpookyHashV2.hash64(data, seed) as an unsigned 64-bit integer."""
    return (_short if len(data) < _SHORT_LIMIT else _long)(data, seed & _MASK)
