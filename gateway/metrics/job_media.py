"""Batch image and video metrics that name jobs rather than files.

ReSim's own isaacsim-demo config has batch `image` metrics whose query returns
`[experience_name, job_id]` (one row per job, e.g. the camera feeds of the scenes with bright
lighting): a label and a job, not a file name. lakegate shows, for each row in order, the files of
that job named in the topic columns of the template's field type (`image` or `video`) of the
branch's config, found in that job's logs, each captioned with the row's label.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from lakegate.gateway.metrics.templates import FILE_COLUMNS, Rendered, TemplateError, display_value, render
from lakegate.lake.template_kinds import TEMPLATES


def names_jobs(template: str | None, columns: Sequence[tuple[str, str]]) -> bool:
    """Whether a result of `template` with these (name, type) columns is `[label, job_id]`."""
    kind = TEMPLATES.get(template or "")
    return kind is not None and kind.names_jobs and len(columns) == 2 and columns[1][0].lower() == "job_id"


def render_job_media(
    metric: str,
    template: str,
    rows: Sequence[tuple],
    media_columns: Sequence[tuple[str, str]],
    files_of: Callable[[str, str, str], list[str]],
    logs_dir_of: Callable[[str], Path | None],
) -> Rendered:
    """The files of each row's job (`files_of(job_id, topic, field)` over `media_columns`, (topic,
    field) pairs typed `template`), found in `logs_dir_of(job_id)`, captioned `label: file`.
    TemplateError when no topic has a column of the template's type."""
    if not media_columns:
        raise TemplateError(
            f"metric {metric!r}: template {template!r} got [label, job_id] rows, but no topic of the branch's "
            f"config has a {template} column to take the jobs' files from"
        )
    found: list[list[Any]] = []
    images: list[str] = []
    problems: list[str] = []
    for label, job_id in rows:
        caption = display_value(label)
        if job_id is None:
            problems.append(f"{caption}: NULL job_id")
            continue
        names = [name for topic, column in media_columns for name in files_of(str(job_id), topic, column)]
        if not names:
            problems.append(f"{caption}: job {job_id} has no {template} files")
            continue
        shown = render(
            metric, template, [("file", "varchar")], [(name,) for name in names], logs_dir=logs_dir_of(job_id)
        )
        found += [[f"{caption}: {row[0]}", *row[1:]] for row in shown.table["rows"]]
        images += shown.images
        problems += [f"{caption}: {problem}" for problem in shown.problems]
    noun = "image" if TEMPLATES[template].shows == "images" else "video"
    text = f"{len(found)} {noun}{'' if len(found) == 1 else 's'} of {len(rows)} job{'' if len(rows) == 1 else 's'}"
    return Rendered(
        template=template,
        table={"columns": FILE_COLUMNS, "rows": found},
        text=text + (f", {len(problems)} problem{'' if len(problems) == 1 else 's'}" if problems else ""),
        images=images,
        problems=problems,
    )
