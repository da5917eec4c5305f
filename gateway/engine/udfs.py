"""The Python functions lakegate's translations call in DuckDB (lakegate.dialect.functions.binary
lists them): `install` registers them on a connection, before it is locked down. They compute
what Trino's VarbinaryFunctions and HmacFunctions compute, byte for byte: sha512 and hmac_sha512
with hashlib/hmac, xxhash64 with the xxhash package (XXH64, seed 0, big-endian as Trino gives the
long), murmur3 with mmh3 (MurmurHash3 x64 128, seed 0, its two longs little-endian as airlift's
Murmur3Hash128), the SpookyHash V2 pair with spooky_hash.py (a port of airlift's SpookyHashV2, seed 0,
big-endian). A function that fails raises a Trino-named error (GENERIC_INTERNAL_ERROR naming it).
The JSONPath and JSON array functions that read text as Trino's streaming parser does are
json_functions.py's (lakegate.dialect.functions.json `STREAMED` lists them).
"""

from __future__ import annotations

import functools
import hashlib
import hmac
import re
from collections.abc import Callable

import duckdb
import mmh3
import xxhash
from duckdb.sqltypes import BIGINT, BLOB, BOOLEAN, DOUBLE, HUGEINT, INTEGER, VARCHAR

from lakegate.dialect import wide_decimals
from lakegate.dialect.functions.binary import UDF_PREFIX, UDFS
from lakegate.dialect.functions.json import STREAMED
from lakegate.gateway.engine import json_functions, spooky_hash

#: Trino name -> the function, its parameters those of the Trino function (DuckDB reads its arity).
_FUNCTIONS: dict[str, Callable[..., bytes]] = {
    "sha512": lambda data: hashlib.sha512(data).digest(),
    "hmac_sha512": lambda data, key: hmac.digest(key, data, "sha512"),
    "xxhash64": lambda data: xxhash.xxh64_digest(data),
    "murmur3": lambda data: mmh3.hash_bytes(data),
    "spooky_hash_v2_32": lambda data: (spooky_hash.hash64(data) & 0xFFFFFFFF).to_bytes(4, "big"),
    "spooky_hash_v2_64": lambda data: spooky_hash.hash64(data).to_bytes(8, "big"),
}

#: The DuckDB types of the streamed JSON functions' parameters and results.
_JSON_TYPES: dict[str, tuple[list, object]] = {
    "json_extract_scalar": ([VARCHAR, VARCHAR], VARCHAR),
    "json_extract": ([VARCHAR, VARCHAR], VARCHAR),
    "json_size": ([VARCHAR, VARCHAR], BIGINT),
    "json_array_length": ([VARCHAR], BIGINT),
    "json_array_get": ([VARCHAR, BIGINT], VARCHAR),
    "json_array_contains_boolean": ([VARCHAR, BOOLEAN], BOOLEAN),
    "json_array_contains_bigint": ([VARCHAR, BIGINT], BOOLEAN),
    "json_array_contains_double": ([VARCHAR, DOUBLE], BOOLEAN),
    "json_array_contains_varchar": ([VARCHAR, VARCHAR], BOOLEAN),
}

#: A message that already names Trino's error (a refusal, or the error Trino raises).
_NAMED = re.compile(r"[A-Z][A-Z_]+: ")


def trino_named(name: str, function: Callable) -> Callable:
    """`function` raising, when it fails, an error that lakegate.dialect.errors.runtime_error
    reads as Trino's GENERIC_INTERNAL_ERROR naming the Trino function `name` (or as the error a
    RuntimeError it raises names)."""

    @functools.wraps(function)  # its signature, whose parameters DuckDB counts
    def call(*args):
        try:
            return function(*args)
        except Exception as error:  # any failure of the library becomes the query's error
            if isinstance(error, RuntimeError) and _NAMED.match(str(error)):
                raise
            raise RuntimeError(f"GENERIC_INTERNAL_ERROR: {name} failed: {error}") from error

    return call


def install(connection: duckdb.DuckDBPyConnection) -> None:
    """Register every function of `UDFS`, the streamed JSON functions and the wide decimal division
    on `connection` (NULL arguments give NULL: without a call, or from the JSON functions, which
    themselves answer NULL)."""
    for name, (count, _) in UDFS.items():
        connection.create_function(
            UDF_PREFIX + name, trino_named(name, _FUNCTIONS[name]), [BLOB] * count, BLOB, side_effects=False
        )
    for name in STREAMED:
        parameters, result = _JSON_TYPES[name]
        function = trino_named(name, getattr(json_functions, name))
        connection.create_function(
            UDF_PREFIX + name, function, parameters, result, null_handling="special", side_effects=False
        )
    connection.create_function(
        wide_decimals.UDF_NAME,
        wide_decimals.divide,
        [HUGEINT, HUGEINT, INTEGER, BOOLEAN],
        HUGEINT,
        side_effects=False,
    )
