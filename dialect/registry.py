"""The function registry: the Trino functions lakegate translates (`SUPPORTED`, filled by `register`
from the modules of lakegate.dialect.functions, one per page of Trino's function reference, which
lakegate.dialect.functions.pages lists and installs) and those it refuses, with the reason
(`REJECTED`). The analyzer and the writer look functions up here; lakegate.dialect.translate fills it
(`pages.install()`) before it translates.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from sqlglot import exp

from lakegate.dialect.trino_types import TType

#: The call's types -> its result type (argument: analyze.Call; Any here, as analyze uses this registry).
Infer = Callable[[Any], TType]

#: (transforms.Writer, the call, its rendered arguments) -> DuckDB SQL.
Render = Callable[[Any, exp.Expression, list], str]


@dataclass(frozen=True)
class FunctionSpec:
    """One supported Trino function."""

    name: str
    family: str
    signature: str  # as Trino documents it, e.g. "cardinality(array(E)) -> bigint"
    kind: str  # scalar | aggregate | window
    infer: Infer
    render: Render
    notes: str = ""


SUPPORTED: dict[str, FunctionSpec] = {}


def register(
    name: str,
    family: str,
    signature: str,
    infer: Infer,
    render: Render,
    kind: str = "scalar",
    notes: str = "",
    aliases: tuple[str, ...] = (),
    replaces: bool = False,
) -> None:
    """Register a function; a name already registered is an error unless `replaces` (an overload
    that extends the registered rule), so two modules never silently define one function."""
    for alias in (name, *aliases):
        if (alias in SUPPORTED) != replaces:
            raise ValueError(f"function {alias!r} is {'not yet' if replaces else 'already'} registered")
        SUPPORTED[alias] = FunctionSpec(alias, family, signature, kind, infer, render, notes)


#: Well-known Trino functions lakegate refuses: name -> why.
REJECTED: dict[str, str] = {}


def overload(name: str, accepts: Callable[[Any], TType | None], render: Render, signature: str) -> None:
    """Add a Trino overload to the registered function `name`: `accepts` types the calls it takes
    (None for the others, which keep the registered rule) and `render` writes them."""
    base = SUPPORTED[name]

    def infer(call: Any) -> TType:
        result = accepts(call)
        if result is None:
            return base.infer(call)
        call.node.meta["overload"] = render
        return result

    def render_either(g: Any, node: exp.Expression, args: list) -> str:  # an earlier overload's calls: base's
        return render(g, node, args) if node.meta.get("overload") is render else base.render(g, node, args)

    register(
        name, base.family, f"{base.signature}; {signature}", infer, render_either, base.kind, base.notes, replaces=True
    )


#: CAST to and from json (lakegate.dialect.json_values fills it, as it builds on the transforms):
#: "to_json" (writer, sql, source type) and "from_json" (writer, sql, target type) -> DuckDB SQL.
JSON_CASTS: dict[str, Callable[[Any, str, TType], str]] = {}
