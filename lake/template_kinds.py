"""The system template kinds of a metric (`template:` in the config), listed once, each a row of data.

Every place that treats kinds differently asks this table: the config schema (which names a config
may give), the renderer (gateway/metrics/templates.py, one renderer per kind), the HTML report and the
dashboard (how a result is shown: `shows`), build comparison (`series`) and batch media per job
(`names_jobs`). Adding a kind is its row here and its renderer.
"""

from __future__ import annotations

from dataclasses import dataclass

#: How a rendered result is shown: a Plotly chart, a chart drawn as a timeline of states, a table,
#: one value, or files of the job's logs (images, video players, download links).
SHOWS = ("chart", "timeline", "table", "scalar", "images", "videos", "files")
#: The ways of showing files of the job's logs.
FILE_SHOWS = ("images", "videos", "files")
#: What build comparison compares of a series kind's figure: the y of each trace, the x of each
#: trace (a histogram's samples), or each segment's state (the trace's name) as a category.
SERIES = ("y", "x", "states")
#: What a result no kind names (a custom template's figure, a report's attached Plotly figure) shows.
DEFAULT_SHOWS = "chart"


@dataclass(frozen=True)
class TemplateKind:
    """One system template kind and how every part of lakegate treats it."""

    name: str
    #: How its rendered result is shown (one of `SHOWS`).
    shows: str
    #: The values of its figure build comparison compares (gateway/metrics/compare.py), one of
    #: `SERIES`; None when its results are not compared as series.
    series: str | None = None
    #: A batch result of `[label, job_id]` rows shows each job's media files (gateway/metrics/job_media.py).
    names_jobs: bool = False

    @property
    def files(self) -> bool:
        """Its result names files of the job's logs, which it shows ([name, path, bytes, MIME type])."""
        return self.shows in FILE_SHOWS

    @property
    def figure(self) -> bool:
        """Its rendered result is a Plotly figure."""
        return self.shows in ("chart", "timeline")


TEMPLATES: dict[str, TemplateKind] = {
    kind.name: kind
    for kind in (
        TemplateKind("line", "chart", series="y"),
        TemplateKind("bar", "chart", series="y"),
        TemplateKind("table", "table"),
        TemplateKind("scalar", "scalar"),
        TemplateKind("image", "images", names_jobs=True),
        TemplateKind("state_timeline", "timeline", series="states"),
        TemplateKind("histogram", "chart", series="x"),
        TemplateKind("pie", "chart"),
        TemplateKind("video", "videos", names_jobs=True),
        TemplateKind("artifact", "files"),
    )
}


def shows(template: str | None) -> str:
    """How a result of `template` is shown (`DEFAULT_SHOWS` for a name that is no system kind)."""
    kind = TEMPLATES.get(template or "")
    return kind.shows if kind is not None else DEFAULT_SHOWS


def series(template: str | None) -> str | None:
    """What build comparison compares of a result of `template` (one of `SERIES`, or None)."""
    kind = TEMPLATES.get(template or "")
    return kind.series if kind is not None else None


def kinds_where(flag: str) -> tuple[str, ...]:
    """The names of the kinds whose `flag` (an attribute or property of `TemplateKind`) is true."""
    return tuple(name for name, kind in TEMPLATES.items() if getattr(kind, flag))
