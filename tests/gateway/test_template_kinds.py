"""The table of template kinds is the one list: the config schema, the renderer, the report and the
dashboard, build comparison and batch media all follow it."""

from __future__ import annotations

import pytest

from lakegate.gateway.metrics import templates
from lakegate.gateway.metrics.compare import SERIES_TEMPLATES
from lakegate.gateway.metrics.job_media import names_jobs
from lakegate.gateway.metrics.templates import Rendered, TemplateError, render
from lakegate.lake.config_schema import json_schema
from lakegate.lake.template_kinds import SERIES, SHOWS, TEMPLATES, kinds_where, shows

JOB_ROWS = [("job_label", "varchar"), ("job_id", "varchar")]


def test_every_kind_has_one_renderer_and_every_renderer_a_kind():
    assert list(templates._RENDERERS) == list(TEMPLATES)


@pytest.mark.parametrize("name", TEMPLATES)
def test_each_row_says_what_it_is(name):
    kind = TEMPLATES[name]
    assert kind.name == name and kind.shows in SHOWS and kind.series in (None, *SERIES)
    assert not (kind.names_jobs and not kind.files), "a kind naming jobs shows their files"


def test_the_config_schema_accepts_exactly_the_kinds():
    metric = json_schema()["$defs"]["metric"]["properties"]["template"]
    assert metric["enum"] == list(TEMPLATES)


def test_an_unknown_kind_is_refused_naming_every_kind():
    with pytest.raises(TemplateError) as caught:
        render("m", "sparkline", [("x", "double")], [(1.0,)])
    assert str(caught.value) == f"metric 'm': unknown template 'sparkline' (expected one of {', '.join(TEMPLATES)})"


def test_the_parts_follow_the_table():
    assert set(SERIES_TEMPLATES) == {n for n, k in TEMPLATES.items() if k.series} >= {"line", "bar", "histogram"}
    assert [n for n in TEMPLATES if names_jobs(n, JOB_ROWS)] == list(kinds_where("names_jobs"))
    assert {"image", "video"} <= set(kinds_where("names_jobs")) and "artifact" not in kinds_where("names_jobs")
    assert {"image", "video", "artifact"} <= set(kinds_where("files")) and "table" not in kinds_where("files")
    assert Rendered(template="custom").shows == "chart" == shows(None)
    assert {n: Rendered(template=n).shows for n in ("table", "scalar", "state_timeline", "artifact")} == {
        "table": "table",
        "scalar": "scalar",
        "state_timeline": "timeline",
        "artifact": "files",
    }
