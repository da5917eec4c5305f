"""The function modules of lakegate.dialect.functions, each the page of Trino's function reference it
mirrors, and `install`, which registers all of them into lakegate.dialect.registry: the one list of
the modules that fill the registry (a new page is added here)."""

from __future__ import annotations

from types import ModuleType

from lakegate.dialect.functions import (
    aggregate,
    array,
    binary,
    bitwise,
    comparison,
    conditional,
    conversion,
    datetime,
    datetime_formats,
    datetime_zoned_times,
    ipaddress,
    json,
    json_constructors,
    lambdas,
    map,
    math,
    refused,
    regexp,
    session,
    string,
    teradata,
    url,
    window,
)
from lakegate.dialect.registry import REJECTED, SUPPORTED

PAGES: tuple[ModuleType, ...] = (
    aggregate,
    array,
    binary,
    bitwise,
    comparison,
    conditional,
    conversion,
    datetime,
    datetime_formats,
    datetime_zoned_times,
    ipaddress,
    json,
    json_constructors,
    lambdas,
    map,
    math,
    refused,
    regexp,
    session,
    string,
    teradata,
    url,
    window,
)


#: Function name -> the name of the page module that registers it (or refuses it), filled by install.
PAGE_OF: dict[str, str] = {}


def install() -> None:
    """Fill the registry from every page, once (later calls do nothing)."""
    if SUPPORTED:
        return
    for page in PAGES:
        before = set(SUPPORTED) | set(REJECTED)
        page.install()
        for name in (set(SUPPORTED) | set(REJECTED)) - before:
            PAGE_OF[name] = page.__name__.rsplit(".", 1)[1]
