"""The hash functions DuckDB has no exact equivalent of (issue 14 family 5): sha512, hmac_sha512,
xxhash64, murmur3, spooky_hash_v2_32 and spooky_hash_v2_64. Each is written as a call of a Python
function that lakegate.gateway.engine.udfs registers on every DuckDB connection the engine opens,
named `UDF_PREFIX` + the Trino name; `UDFS` lists them with their arity (varbinary arguments,
varbinary result; NULL in, NULL out).

Sources: trinodb/trino core/trino-main/src/main/java/io/trino/operator/scalar/VarbinaryFunctions.java
and HmacFunctions.java; expected values in tests/dialect/cases/cov_hashes.yaml.
"""

from __future__ import annotations

from lakegate.dialect import trino_types as tt
from lakegate.dialect.analyze import Call
from lakegate.dialect.functions import sqls
from lakegate.dialect.functions_scalar import hmac_key_checked
from lakegate.dialect.registry import Infer, Render, register

#: The prefix of the DuckDB names of these functions (not callable from Trino SQL: the analyzer
#: knows only registered names).
UDF_PREFIX = "lakegate_"

#: Trino name -> (number of varbinary arguments, signature as Trino documents it).
UDFS: dict[str, tuple[int, str]] = {
    "sha512": (1, "sha512(binary) -> varbinary"),
    "hmac_sha512": (2, "hmac_sha512(binary, key) -> varbinary"),
    "xxhash64": (1, "xxhash64(binary) -> varbinary"),
    "murmur3": (1, "murmur3(binary) -> varbinary"),
    "spooky_hash_v2_32": (1, "spooky_hash_v2_32(binary) -> varbinary"),
    "spooky_hash_v2_64": (1, "spooky_hash_v2_64(binary) -> varbinary"),
}


def _binary_args(count: int) -> Infer:
    def infer(call: Call) -> tt.TType:
        if len(call.args) != count or any(t is None or t.base not in ("varbinary", "unknown") for t in call.types):
            call.mismatch()
        return tt.VARBINARY

    return infer


def _render(name: str) -> Render:
    def render(g, node, args) -> str:
        values = sqls(g, args)
        sql = f"{UDF_PREFIX}{name}({', '.join(values)})"
        return hmac_key_checked(values[1], sql) if name.startswith("hmac_") else sql

    return render


for _name, (_count, _signature) in UDFS.items():
    register(_name, "binary", _signature, _binary_args(_count), _render(_name))
