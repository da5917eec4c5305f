"""Metric templates: result shapes, Plotly figures, JSON safety and offline HTML pages."""

from __future__ import annotations

import base64
import datetime as dt
import json
import os
import re
import struct
import subprocess
import sys
import zlib
from decimal import Decimal

import numpy as np
import plotly.graph_objects as go
import pytest
from plotly.offline import get_plotlyjs

from lakegate.gateway.metrics.figures_html import figure_html, file_size, report_html
from lakegate.gateway.metrics.plotly_arrays import plain
from lakegate.gateway.metrics.templates import (
    PALETTE,
    STATUS_COLOURS,
    TemplateError,
    format_number,
    render,
    state_colours,
)

LINE_COLUMNS = [("group_name", "varchar"), ("Time (s)", "double"), ("Distance to Goal (m)", "double")]
TIMELINE_COLUMNS = [("System", "varchar"), ("timestamp", "bigint"), ("state", "varchar")]
GIF = (
    b"GIF89a\x01\x00\x01\x00\x80\x00\x00\xff\xff\xff\x00\x00\x00!\xf9\x04\x01\x00\x00\x00\x00"
    b",\x00\x00\x00\x00\x01\x00\x01\x00\x00\x02\x02D\x01\x00;"
)
PLOTLYJS_HEAD = get_plotlyjs()[:40]
NETWORK_SCRIPT = re.compile(r"<script[^>]*\ssrc\s*=\s*[\"']?(https?:)?//", re.IGNORECASE)


def png_bytes() -> bytes:
    """A valid 1x1 red PNG."""

    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))

    header = struct.pack(">IIBBBBB", 1, 1, 8, 2, 0, 0, 0)
    return (
        b"\x89PNG\r\n\x1a\n"
        + chunk(b"IHDR", header)
        + chunk(b"IDAT", zlib.compress(b"\x00\xff\x00\x00"))
        + chunk(b"IEND", b"")
    )


def check_figure(figure: dict) -> None:
    """The figure is strict JSON and valid against Plotly's schema."""
    json.dumps(figure, allow_nan=False)
    go.Figure(figure)  # raises on any property Plotly does not know


def plots_in(page: str) -> list[tuple[list, dict]]:
    """The (data, layout) of every Plotly.newPlot call in a page, decoded as JSON."""
    decoder = json.JSONDecoder()
    plots = []
    for match in re.finditer(r'<script>Plotly\.newPlot\("[^"]+", ', page):
        data, end = decoder.raw_decode(page, match.end())
        layout, _ = decoder.raw_decode(page, end + 2)
        plots.append((data, layout))
    return plots


# -- line and bar -----------------------------------------------------------------------------------------


def test_line_has_one_trace_per_series_in_first_appearance_order():
    rows = [("goal_2", 0.0, 5.0), ("goal_1", 0.0, 9.0), ("goal_2", 1.5, 4.0), ("goal_1", 1.5, 8.5), ("goal_2", 3, 3)]
    rendered = render("Distance to Goal", "line", LINE_COLUMNS, rows)
    check_figure(rendered.figure)
    traces = rendered.figure["data"]
    assert [t["name"] for t in traces] == ["goal_2", "goal_1"]
    assert traces[0]["x"] == [0.0, 1.5, 3] and traces[0]["y"] == [5.0, 4.0, 3]
    assert traces[1]["x"] == [0.0, 1.5] and traces[1]["y"] == [9.0, 8.5]
    assert {t["type"] for t in traces} == {"scatter"}
    layout = rendered.figure["layout"]
    assert layout["xaxis"]["title"]["text"] == "Time (s)"
    assert layout["yaxis"]["title"]["text"] == "Distance to Goal (m)"
    assert rendered.text == "2 series, 5 points"
    assert rendered.problems == []


def test_line_accepts_decimal_numpy_and_timestamps_and_stays_json_safe():
    rows = [
        ("a", dt.datetime(2024, 5, 1, 12, 0, 0), Decimal("1.25")),
        ("a", dt.datetime(2024, 5, 1, 12, 0, 1, 500000, tzinfo=dt.UTC), np.float64(2.5)),
        ("a", dt.datetime(2024, 5, 1, 12, 0, 2), np.int64(3)),
        ("a", dt.datetime(2024, 5, 1, 12, 0, 3), float("nan")),
        ("a", dt.datetime(2024, 5, 1, 12, 0, 4), None),
    ]
    rendered = render("Speed", "line", [("s", "varchar"), ("t", "timestamp(3)"), ("v", "double")], rows)
    check_figure(rendered.figure)
    trace = rendered.figure["data"][0]
    assert trace["x"][:2] == ["2024-05-01 12:00:00", "2024-05-01 12:00:01.500000"]
    assert trace["y"] == [1.25, 2.5, 3, None, None]
    assert rendered.figure["layout"]["xaxis"]["type"] == "date"
    assert rendered.problems == ['1 value of "v" is NaN or infinite and not drawn']


def test_line_needs_three_columns():
    with pytest.raises(TemplateError) as error:
        render("Robot Speed", "line", [("a", "varchar"), ("b", "double")], [("x", 1.0)])
    assert str(error.value) == (
        "metric 'Robot Speed': template 'line' needs exactly 3 columns [series, x, y] "
        "(and an optional link_path column), got 2 (a, b)"
    )
    with pytest.raises(TemplateError, match=r"takes a 4th column only named link_path, got 4 \(a, b, c, d\)"):
        render("Robot Speed", "line", [(n, "double") for n in "abcd"], [])


def test_line_rejects_non_numeric_y_naming_the_row():
    rows = [("s", 0.0, 1.0), ("s", 1.0, 2.0), ("s", 2.0, "fast")]
    with pytest.raises(TemplateError) as error:
        render("Robot Speed", "line", LINE_COLUMNS, rows)
    assert str(error.value) == (
        "metric 'Robot Speed': template 'line' needs numeric y values in column 3 \"Distance to Goal (m)\", "
        "but row 3 has 'fast' (double)"
    )


def test_line_rejects_text_and_boolean_x():
    with pytest.raises(TemplateError, match=r"numeric or timestamp x values .* row 2 has 'later'"):
        render("Robot Speed", "line", LINE_COLUMNS, [("s", 0.0, 1.0), ("s", "later", 2.0)])
    with pytest.raises(TemplateError, match=r"row 1 has True"):
        render("Robot Speed", "line", LINE_COLUMNS, [("s", True, 1.0)])


def test_rows_must_match_the_columns():
    with pytest.raises(TemplateError, match=r"got row 2 with 2 values for 3 columns"):
        render("Robot Speed", "line", LINE_COLUMNS, [("s", 0.0, 1.0), ("s", 1.0)])


def test_bar_keeps_categorical_x_as_categories():
    columns = [("_col0", "varchar"), ("Experience Name", "varchar"), ("Maximum Localization Error (m)", "double")]
    rows = [("Maximum", "001", 0.5), ("Maximum", "002", Decimal("0.75")), ("Minimum", "001", 0.1)]
    rendered = render("Maximum Localization Error", "bar", columns, rows)
    check_figure(rendered.figure)
    traces = rendered.figure["data"]
    assert [(t["type"], t["name"], t["x"], t["y"]) for t in traces] == [
        ("bar", "Maximum", ["001", "002"], [0.5, 0.75]),
        ("bar", "Minimum", ["001"], [0.1]),
    ]
    layout = rendered.figure["layout"]
    assert layout["xaxis"] == {"title": {"text": "Experience Name"}, "type": "category"}
    assert layout["yaxis"]["title"]["text"] == "Maximum Localization Error (m)"
    assert layout["barmode"] == "group"


def test_bar_with_numeric_x_keeps_numbers():
    rendered = render("Per goal", "bar", [("s", "varchar"), ("goal", "bigint"), ("t", "double")], [("s", 1, 2.0)])
    assert rendered.figure["data"][0]["x"] == [1]
    assert "type" not in rendered.figure["layout"]["xaxis"]


def test_bar_shape_errors():
    with pytest.raises(
        TemplateError, match=r"template 'bar' needs 2 or 3 columns \[x, y\] or \[series, x, y\] .*, got 1 \(x\)"
    ):
        render("M", "bar", [("x", "varchar")], [("a",)])
    with pytest.raises(TemplateError, match=r"needs numeric y values in column 3 \"v\", but row 1 has '3' \(varchar\)"):
        render("M", "bar", [("s", "varchar"), ("x", "varchar"), ("v", "varchar")], [("s", "a", "3")])


# -- table and scalar ---------------------------------------------------------------------------------------


def test_table_keeps_headers_and_row_order_in_figure_and_dict():
    columns = [("Metric", "varchar"), ("Value", "varchar"), ("n", "bigint")]
    rows = [("Total Samples", "300", 3), ("Within 1σ (target: ~68%)", "67.3%", 1), ("Alpha", None, 2)]
    rendered = render("AMCL Covariance Calibration", "table", columns, rows)
    check_figure(rendered.figure)
    assert rendered.table == {
        "columns": ["Metric", "Value", "n"],
        "rows": [["Total Samples", "300", 3], ["Within 1σ (target: ~68%)", "67.3%", 1], ["Alpha", None, 2]],
    }
    trace = rendered.figure["data"][0]
    assert trace["type"] == "table"
    assert trace["header"]["values"] == ["Metric", "Value", "n"]
    assert trace["cells"]["values"] == [
        ["Total Samples", "Within 1σ (target: ~68%)", "Alpha"],
        ["300", "67.3%", "NULL"],
        ["3", "1", "2"],
    ]
    assert rendered.text == "3 rows, 3 columns"


def test_table_cells_are_json_safe_like_the_trino_protocol():
    columns = [(name, "x") for name in ("dec", "nan", "inf", "ts", "day", "arr", "row", "np", "flag", "bin")]
    row = (
        Decimal("12.50"),
        float("nan"),
        float("-inf"),
        dt.datetime(2024, 1, 2, 3, 4, 5, 123000),
        dt.date(2024, 1, 2),
        ["a", None],
        {"x": 1, "y": Decimal("2.5")},
        np.float32(0.5),
        np.bool_(True),
        b"\x01\xff",
    )
    rendered = render("All types", "table", columns, [row])
    json.dumps(rendered.table, allow_nan=False)
    check_figure(rendered.figure)
    assert rendered.table["rows"][0] == [
        "12.50",
        "NaN",
        "-Infinity",
        "2024-01-02 03:04:05.123000",
        "2024-01-02",
        ["a", None],
        {"x": 1, "y": "2.5"},
        0.5,
        True,
        "01 ff",
    ]
    cells = [column[0] for column in rendered.figure["data"][0]["cells"]["values"]]
    assert cells[:3] == ["12.5", "NaN", "-Infinity"]
    assert cells[5:7] == ["[a, NULL]", "{x=1, y=2.5}"]
    assert cells[8] == "true"


def test_scalar_shows_a_readable_value_with_units_and_keeps_full_precision():
    rendered = render("Time to reach final goal", "scalar", [("_col0", "double")], [(12.500000000001,)], units="s")
    assert rendered.scalar == 12.500000000001
    assert rendered.text == "12.5 s"
    assert rendered.figure is None and rendered.problems == []


def test_scalar_of_other_kinds():
    assert render("M", "scalar", [("c", "decimal(3,1)")], [(Decimal("75.0"),)]).scalar == Decimal("75.0")
    numpy_value = render("M", "scalar", [("c", "double")], [(np.float64(0.25),)], units="m").scalar
    assert type(numpy_value) is float and numpy_value == 0.25
    assert render("M", "scalar", [("c", "bigint")], [(123456789012,)], units="rows").text == "123456789012 rows"
    assert render("M", "scalar", [("c", "double")], [(None,)]).text == "NULL"
    assert render("M", "scalar", [("c", "varchar")], [("ok",)]).text == "ok"


def test_scalar_uses_the_first_value_and_says_what_it_left_out():
    rendered = render("M", "scalar", [("a", "bigint"), ("b", "bigint")], [(1, 2), (3, 4)])
    assert rendered.scalar == 1
    assert rendered.problems == ["the query returned 2 rows and 2 columns; only the first value is shown"]


def test_scalar_with_no_rows_is_an_error():
    with pytest.raises(TemplateError) as error:
        render("Average Speed", "scalar", [("_col0", "double")], [])
    assert str(error.value) == (
        "metric 'Average Speed': template 'scalar' needs 1 row, but the query returned no rows (columns: _col0)"
    )


@pytest.mark.parametrize(
    "value, text",
    [
        (12.500000000001, "12.5"),
        (0.1 + 0.2, "0.3"),
        (1234567.8, "1234568"),
        (-3.25, "-3.25"),
        (0.000123456789, "0.000123457"),
        (1e-7, "1e-07"),
        (2.5e20, "2.5e+20"),
        (0.0, "0"),
        (Decimal("12.50"), "12.5"),
        (Decimal("3.14159265358979"), "3.14159"),
        (10**20, "100000000000000000000"),
        (float("nan"), "NaN"),
        (float("inf"), "Infinity"),
    ],
)
def test_format_number(value, text):
    assert format_number(value) == text


# -- image ---------------------------------------------------------------------------------------------------


def test_image_resolves_files_and_reports_missing_ones(tmp_path):
    logs = tmp_path / "logs"
    (logs / "camera").mkdir(parents=True)
    (logs / "camera" / "feed.gif").write_bytes(GIF)
    (logs / "front.png").write_bytes(png_bytes())
    (logs / "notes.txt").write_text("not an image")
    (tmp_path / "secret.png").write_bytes(png_bytes())
    rows = [("camera/feed.gif",), ("front.png",), ("gone.gif",), ("notes.txt",), ("../secret.png",), (None,)]
    rendered = render("Stereo Camera Feed", "image", [("filename", "varchar")], rows, logs_dir=logs)
    resolved = logs.resolve()
    assert rendered.images == [str(resolved / "camera" / "feed.gif"), str(resolved / "front.png")]
    assert rendered.problems == [
        f"gone.gif: missing from the job's logs ({resolved})",
        "notes.txt: not a PNG, GIF or JPEG image",
        f"../secret.png: outside the job's logs ({resolved})",
        "row 6: NULL file name",
    ]
    assert rendered.table["rows"][1] == ["front.png", str(resolved / "front.png"), len(png_bytes()), "image/png"]
    assert rendered.text == "2 images, 4 problems"

    page = figure_html(rendered, title="Stereo Camera Feed")
    assert page.count('<img src="data:image/gif;base64,') == 1
    assert page.count('<img src="data:image/png;base64,') == 1
    assert "gone.gif: missing from the job&#x27;s logs" in page
    assert PLOTLYJS_HEAD not in page  # no chart, no plotly.js
    assert not re.search(r"<img[^>]*src=\"(?!data:)", page)


def test_image_without_logs_dir_reports_every_file():
    rendered = render("Feed", "image", [("filename", "varchar")], [("a.gif",)])
    assert rendered.images == [] and rendered.problems == ["a.gif: no log directory to look in"]


def test_image_problems_are_one_line_per_cause_with_a_count(tmp_path):
    rows = [(f"frame_{i:03}.png",) for i in range(200)] + [(None,), (None,)]
    rendered = render("Feed", "image", [("filename", "varchar")], rows)
    assert rendered.problems == [
        "200 files: no log directory to look in (frame_000.png, frame_001.png, frame_002.png and 197 more)",
        "2 rows: NULL file name (row 201, row 202)",
    ]
    assert rendered.text == "0 images, 202 problems"
    rendered = render("Feed", "image", [("filename", "varchar")], rows[:2], logs_dir=tmp_path)
    assert rendered.problems == [
        f"2 files: missing from the job's logs ({tmp_path.resolve()}) (frame_000.png, frame_001.png)"
    ]


def test_image_shape_errors(tmp_path):
    with pytest.raises(
        TemplateError, match=r"template 'image' needs exactly 1 column \[image file name\], got 2 \(a, b\)"
    ):
        render("Feed", "image", [("a", "varchar"), ("b", "varchar")], [], logs_dir=tmp_path)
    with pytest.raises(TemplateError, match=r"needs image file names in column 1 \"f\", but row 1 has 7 \(bigint\)"):
        render("Feed", "image", [("f", "bigint")], [(7,)], logs_dir=tmp_path)


# -- state timeline ----------------------------------------------------------------------------------------


def test_state_timeline_merges_consecutive_states_per_system():
    s = 10**9
    rows = [  # out of timestamp order on purpose; the arm starts before the navigation's first row
        ("Navigation", 102 * s, "IDLE"),
        ("Navigation", 103 * s, "ACTIVE"),
        ("Navigation", 104 * s, "ACTIVE"),
        ("Arm", 100 * s, "IDLE"),
        ("Navigation", 106 * s, "SUCCEEDED"),
        ("Navigation", 105 * s, "ACTIVE"),
        ("Arm", 101 * s, "IDLE"),
        ("Navigation", 107 * s, "ACTIVE"),
    ]
    rendered = render("Goal Status", "state_timeline", TIMELINE_COLUMNS, rows)
    check_figure(rendered.figure)
    assert rendered.table == {
        "columns": ["System", "state", "start (s)", "end (s)"],
        "rows": [
            ["Navigation", "IDLE", 2.0, 3.0],
            ["Navigation", "ACTIVE", 3.0, 6.0],
            ["Navigation", "SUCCEEDED", 6.0, 7.0],
            ["Navigation", "ACTIVE", 7.0, 7.0],
            ["Arm", "IDLE", 0.0, 7.0],
        ],
    }
    layout = rendered.figure["layout"]
    assert layout["xaxis"]["title"]["text"] == "Elapsed time (s)"
    assert layout["yaxis"]["title"]["text"] == "System"
    assert layout["barmode"] == "overlay"
    traces = {t["name"]: t for t in rendered.figure["data"]}
    assert list(traces) == ["IDLE", "ACTIVE", "SUCCEEDED"]
    assert all(t["type"] == "bar" and t["orientation"] == "h" for t in traces.values())
    assert traces["ACTIVE"]["y"] == ["Navigation", "Navigation"]
    assert traces["ACTIVE"]["base"] == [3.0, 7.0]
    assert traces["ACTIVE"]["x"][0] == 3.0
    assert traces["ACTIVE"]["x"][1] > 0  # a state seen only at the end still shows
    assert traces["ACTIVE"]["customdata"] == [[3.0, 6.0], [7.0, 7.0]]
    assert traces["IDLE"]["y"] == ["Navigation", "Arm"] and traces["IDLE"]["x"] == [1.0, 7.0]
    colours = state_colours(traces)
    for name, trace in traces.items():
        assert trace["marker"]["color"] == colours[name]
    assert layout["yaxis"]["automargin"] is True  # the axis title clears the systems' names
    assert rendered.text == "2 systems, 5 segments, 3 states"


def test_state_colours_are_stable_across_metrics_and_processes():
    first = render("A", "state_timeline", TIMELINE_COLUMNS, [("x", 0, "ACTIVE"), ("x", 5, "FAILED")])
    second = render(
        "B",
        "state_timeline",
        [("Robot", "varchar"), ("t", "bigint"), ("s", "varchar")],
        [("y", 9, "FAILED"), ("y", 10, "IDLE"), ("y", 11, "ACTIVE")],
    )
    colours_a = {t["name"]: t["marker"]["color"] for t in first.figure["data"]}
    colours_b = {t["name"]: t["marker"]["color"] for t in second.figure["data"]}
    assert colours_a["ACTIVE"] == colours_b["ACTIVE"] and colours_a["FAILED"] == colours_b["FAILED"]
    assert set(colours_a.values()) | set(colours_b.values()) <= set(PALETTE)
    code = (
        "from lakegate.gateway.metrics.templates import state_colours; "
        "colours = state_colours(['FAILED', 'ACTIVE']); print(colours['ACTIVE'], colours['FAILED'])"
    )
    outputs = [  # Python's own hash() of a str differs between these processes; the colours must not
        subprocess.run(
            [sys.executable, "-c", code],
            capture_output=True,
            text=True,
            check=True,
            env={**os.environ, "PYTHONHASHSEED": seed},
        ).stdout.split()
        for seed in ("1", "2")
    ]
    assert outputs == [[colours_a["ACTIVE"], colours_a["FAILED"]]] * 2


def test_states_of_one_timeline_never_share_a_colour():
    # WAITING and REACHED (the demo's goal states) fall in one palette slot of 16 colours: each still
    # gets its own, and keeps it in a job without the other states (one that never aborted)
    goal_states = ["WAITING", "NAVIGATING", "REACHED", "ABORTED"]
    demo = render("Goal Status", "state_timeline", TIMELINE_COLUMNS, [("g", t, s) for t, s in enumerate(goal_states)])
    colours = {t["name"]: t["marker"]["color"] for t in demo.figure["data"]}
    assert len(set(colours.values())) == 4
    fewer = render("Goal Status", "state_timeline", TIMELINE_COLUMNS, [("g", 0, "WAITING"), ("g", 1, "REACHED")])
    assert {t["name"]: t["marker"]["color"] for t in fewer.figure["data"]} == {
        "WAITING": colours["WAITING"],
        "REACHED": colours["REACHED"],
    }
    # every palette colour in use, and states named as statuses in their badge colours: still all distinct
    states = [*goal_states, "PASSED", "BLOCKER", *(f"STATE_{i}" for i in range(len(PALETTE) - 4))]
    rendered = render("Many", "state_timeline", TIMELINE_COLUMNS, [("g", t, s) for t, s in enumerate(states)])
    colours = {t["name"]: t["marker"]["color"] for t in rendered.figure["data"]}
    assert len(set(colours.values())) == len(states)
    assert colours["PASSED"] == STATUS_COLOURS["PASSED"] and colours["BLOCKER"] == STATUS_COLOURS["BLOCKER"]


def test_charts_of_statuses_draw_the_badge_colours():
    pie = render("Job Outcomes", "pie", [("s", "varchar"), ("n", "bigint")], [("BLOCKER", 2), ("PASSED", 5)])
    assert pie.figure["data"][0]["marker"]["colors"] == [STATUS_COLOURS["BLOCKER"], STATUS_COLOURS["PASSED"]]
    bars = render("By status", "bar", [("s", "varchar"), ("n", "bigint")], [("WARNING", 1), ("ERROR", 3)])
    assert bars.figure["data"][0]["marker"]["color"] == [STATUS_COLOURS["WARNING"], STATUS_COLOURS["ERROR"]]
    series = render("Per status", "line", LINE_COLUMNS, [("PASSED", 0, 1), ("PASSED", 1, 2), ("BLOCKER", 0, 3)])
    assert [t["line"]["color"] for t in series.figure["data"]] == [STATUS_COLOURS["PASSED"], STATUS_COLOURS["BLOCKER"]]
    other = render("Not statuses", "pie", [("s", "varchar"), ("n", "bigint")], [("PASSED", 2), ("maybe", 5)])
    assert "marker" not in other.figure["data"][0]  # Plotly's own colours when not every label is a status


def test_one_summary_of_small_pies_and_two_column_tables():
    # the one-line summary (value_text: the CLI table, JSON, the report's and dashboard's job matrix)
    pie = render("P", "pie", [("s", "varchar"), ("n", "bigint")], [("BLOCKER", 2), ("PASSED", 2.5)])
    assert pie.text == "BLOCKER: 2; PASSED: 2.5"
    table = render("T", "table", [("k", "varchar"), ("v", "double")], [("a", 1 / 3), ("b", None)])
    assert table.text == "a: 0.333333; b: NULL"
    many = [(f"s{i}", i) for i in range(7)]
    assert render("P", "pie", [("s", "varchar"), ("n", "bigint")], many).text == "7 slices"
    assert render("T", "table", [("s", "varchar"), ("n", "bigint")], many).text == "7 rows, 2 columns"


def test_state_timeline_errors():
    with pytest.raises(
        TemplateError, match=r"needs exactly 3 columns \[system, timestamp, state\], got 2 \(System, state\)"
    ):
        render("Goal Status", "state_timeline", [("System", "varchar"), ("state", "varchar")], [])
    with pytest.raises(
        TemplateError, match=r"needs timestamps in nanoseconds in column 2 \"timestamp\", but row 2 has NULL"
    ):
        render("Goal Status", "state_timeline", TIMELINE_COLUMNS, [("N", 1, "A"), ("N", None, "B")])
    with pytest.raises(TemplateError, match=r"row 1 has 'soon' \(bigint\)"):
        render("Goal Status", "state_timeline", TIMELINE_COLUMNS, [("N", "soon", "A")])


# -- histogram and pie --------------------------------------------------------------------------------------


def test_histogram_with_and_without_series():
    rendered = render("Speed Distribution", "histogram", [("Speed (m/s)", "double")], [(1.0,), (1.5,), (None,), (2,)])
    check_figure(rendered.figure)
    assert rendered.figure["data"] == [{"type": "histogram", "x": [1.0, 1.5, None, 2]}]
    assert rendered.figure["layout"]["xaxis"]["title"]["text"] == "Speed (m/s)"
    assert rendered.figure["layout"]["yaxis"]["title"]["text"] == "Count"
    assert rendered.text == "3 values" and rendered.problems == ["1 NULL value not counted"]

    rendered = render(
        "Speed", "histogram", [("v", "double"), ("goal", "varchar")], [(1.0, "b"), (2.0, "a"), (3.0, "b")]
    )
    check_figure(rendered.figure)
    assert [(t["name"], plain(t["x"])) for t in rendered.figure["data"]] == [("b", [1.0, 3.0]), ("a", [2.0])]


def test_histogram_takes_resims_group_name_first_shape():
    columns = [("group_name", "varchar"), ("Speed (m/s)", "double")]
    rendered = render("Speed", "histogram", columns, [("b", 1.0), ("a", 2.0), ("b", None), ("b", 3.0)])
    check_figure(rendered.figure)
    assert [(t["name"], t["x"]) for t in rendered.figure["data"]] == [("b", [1.0, None, 3.0]), ("a", [2.0])]
    assert rendered.figure["layout"]["xaxis"]["title"]["text"] == "Speed (m/s)"
    assert rendered.text == "3 values in 2 series" and rendered.problems == ["1 NULL value not counted"]


def test_line_draws_text_x_values_as_categories():
    columns = [("group_name", "varchar"), ("Experience", "varchar"), ("Max speed (m/s)", "double")]
    rendered = render("Speed", "line", columns, [("max", "parking", 1.5), ("max", "highway", 3.0), ("max", None, 2.0)])
    check_figure(rendered.figure)
    assert rendered.figure["data"][0]["x"] == ["parking", "highway", None]
    assert rendered.figure["layout"]["xaxis"]["type"] == "category"


def test_histogram_errors():
    with pytest.raises(
        TemplateError, match=r"needs 1 or 2 columns \[value\], \[value, series\] or \[group, value\], got 3 \(a, b, c\)"
    ):
        render("H", "histogram", [("a", "double"), ("b", "double"), ("c", "double")], [])
    with pytest.raises(TemplateError, match=r"needs numeric values in column 1 \"a\", but row 2 has 'x' \(varchar\)"):
        render("H", "histogram", [("a", "varchar")], [(1.0,), ("x",)])


def test_pie_keeps_query_order():
    columns = [("job_conflated_status", "varchar"), ("_col1", "bigint")]
    rendered = render("Job Outcomes", "pie", columns, [("PASSED", 7), ("BLOCKER", 2), ("WARNING", 1)])
    check_figure(rendered.figure)
    trace = rendered.figure["data"][0]
    assert (trace["type"], trace["labels"], trace["values"], trace["sort"]) == (
        "pie",
        ["PASSED", "BLOCKER", "WARNING"],
        [7, 2, 1],
        False,
    )
    assert rendered.text == "PASSED: 7; BLOCKER: 2; WARNING: 1"


def test_pie_errors():
    with pytest.raises(TemplateError, match=r"template 'pie' needs exactly 2 columns \[label, value\], got 1 \(a\)"):
        render("P", "pie", [("a", "varchar")], [])
    with pytest.raises(TemplateError, match=r"needs non-negative numeric values in column 2 \"n\", but row 2 has -1"):
        render("P", "pie", [("l", "varchar"), ("n", "bigint")], [("a", 1), ("b", -1)])


# -- unsupported and unknown --------------------------------------------------------------------------------


# -- video and artifact -------------------------------------------------------------------------------------

MP4 = b"\x00\x00\x00\x18ftypmp42\x00\x00\x00\x00mp42isom" + bytes(40)  # an ISO media file's first box
WEBM = b"\x1a\x45\xdf\xa3\x9f\x42\x86\x81\x01" + bytes(23)  # an EBML header


def test_video_plays_mp4_webm_and_gif_from_the_logs_and_groups_missing_files(tmp_path):
    logs = tmp_path / "logs"
    (logs / "cams").mkdir(parents=True)
    (logs / "cams" / "front.mp4").write_bytes(MP4)
    (logs / "side.webm").write_bytes(WEBM)
    (logs / "loop.gif").write_bytes(GIF)
    (logs / "notes.txt").write_text("not a video")
    rows = [("cams/front.mp4",), ("side.webm",), ("loop.gif",), ("notes.txt",)]
    rows += [(f"lost_{i}.mp4",) for i in range(5)]
    rendered = render("Replay", "video", [("video", "varchar")], rows, logs_dir=logs)
    resolved = logs.resolve()
    assert rendered.table == {
        "columns": ["file", "path", "bytes", "type"],
        "rows": [
            ["cams/front.mp4", str(resolved / "cams" / "front.mp4"), len(MP4), "video/mp4"],
            ["side.webm", str(resolved / "side.webm"), len(WEBM), "video/webm"],
            ["loop.gif", str(resolved / "loop.gif"), len(GIF), "image/gif"],
        ],
    }
    assert rendered.problems == [
        "notes.txt: not an MP4, WebM or GIF video",
        f"5 files: missing from the job's logs ({resolved}) (lost_0.mp4, lost_1.mp4, lost_2.mp4 and 2 more)",
    ]
    assert rendered.text == "3 videos, 6 problems" and rendered.images == []
    page = figure_html(rendered, title="Replay")
    players = re.findall(r'<video controls preload="metadata" src="data:(video/[a-z0-9]+);base64,([^"]+)"', page)
    assert [(mime, base64.b64decode(data)) for mime, data in players] == [("video/mp4", MP4), ("video/webm", WEBM)]
    assert page.count('<img src="data:image/gif;base64,') == 1
    assert "5 files: missing from the job&#x27;s logs" in page and PLOTLYJS_HEAD not in page


def test_artifact_lists_downloadable_files_with_sizes(tmp_path):
    (tmp_path / "run").mkdir()
    (tmp_path / "run" / "trace.bin").write_bytes(bytes(range(256)) * 8)  # 2 KiB
    (tmp_path / "summary.txt").write_text("ok\n")
    rows = [("run/trace.bin",), ("summary.txt",), ("gone.log",), (None,)]
    rendered = render("Logs", "artifact", [("file", "varchar")], rows, logs_dir=tmp_path)
    assert [row[0::2] for row in rendered.table["rows"]] == [["run/trace.bin", 2048], ["summary.txt", 3]]
    assert rendered.problems == [
        f"gone.log: missing from the job's logs ({tmp_path.resolve()})",
        "row 4: NULL file name",
    ]
    assert rendered.text == "2 files, 2 problems"
    page = figure_html(rendered, title="Logs")
    links = re.findall(r'<a href="data:application/octet-stream;base64,([^"]+)" download="([^"]+)">([^<]+)</a>', page)
    assert [(base64.b64decode(data), download, label) for data, download, label in links] == [
        (bytes(range(256)) * 8, "trace.bin", "run/trace.bin"),
        (b"ok\n", "summary.txt", "summary.txt"),
    ]
    assert "<td>2 KiB</td>" in page and "<td>3 B</td>" in page


@pytest.mark.parametrize("template", ["video", "artifact"])
def test_video_and_artifact_shape_errors_and_no_logs(template):
    with pytest.raises(TemplateError, match=rf"template '{template}' needs exactly 1 column \[{template} file name\]"):
        render("Clip", template, [("a", "varchar"), ("b", "varchar")], [])
    rendered = render("Clip", template, [("f", "varchar")], [("a.mp4",)])
    assert rendered.problems == ["a.mp4: no log directory to look in"] and rendered.table["rows"] == []


@pytest.mark.parametrize(("size", "text"), [(0, "0 B"), (1023, "1023 B"), (1536, "1.5 KiB"), (20 << 20, "20 MiB")])
def test_file_size(size, text):
    assert file_size(size) == text


def test_unknown_template_names_are_errors():
    with pytest.raises(TemplateError, match=r"metric 'Mine': unknown template 'sparkline'"):
        render("Mine", "sparkline", LINE_COLUMNS, [])


# -- HTML ----------------------------------------------------------------------------------------------------


def test_figure_html_is_a_standalone_offline_page():
    rendered = render("Robot Speed", "line", LINE_COLUMNS, [("Speed", 0.0, 1.0), ("Speed", 1.0, 2.0)])
    page = figure_html(rendered, title="Robot Speed")
    assert page.startswith("<!DOCTYPE html>")
    assert page.count(PLOTLYJS_HEAD) == 1
    assert not NETWORK_SCRIPT.search(page)
    [(data, layout)] = plots_in(page)
    assert data == rendered.figure["data"] and layout == rendered.figure["layout"]

    fragment = figure_html(rendered, title="Robot Speed", include_plotlyjs=False, full_html=False)
    assert PLOTLYJS_HEAD not in fragment and "<html" not in fragment and len(plots_in(fragment)) == 1
    local = figure_html(rendered, title="Robot Speed", include_plotlyjs="/static/plotly.min.js")
    assert '<script src="/static/plotly.min.js"></script>' in local
    for remote in ("cdn", "https://cdn.plot.ly/plotly-2.0.min.js", "//cdn.plot.ly/plotly.js"):
        with pytest.raises(ValueError, match="network"):
            figure_html(rendered, title="Robot Speed", include_plotlyjs=remote)


def test_html_escapes_names_and_embedded_json():
    rows = [("</script><script>alert(1)</script>", 0.0, 1.0)]
    rendered = render("Robot Speed", "line", LINE_COLUMNS, rows)
    page = figure_html(rendered, title="<b>Speed</b> & more", include_plotlyjs=False)
    assert "alert(1)</script>" not in page
    assert "<title>&lt;b&gt;Speed&lt;/b&gt; &amp; more</title>" in page
    [(data, _)] = plots_in(page)
    assert data[0]["name"] == "</script><script>alert(1)</script>"


def test_report_embeds_plotlyjs_once_for_many_figures(tmp_path):
    (tmp_path / "cam.gif").write_bytes(GIF)
    line = render("Robot Speed", "line", LINE_COLUMNS, [("Speed", 0.0, 1.0), ("Speed", 1.0, 2.5)])
    bar = render("Max Error", "bar", LINE_COLUMNS, [("Max", 1.0, 0.5)])
    timeline = render("Goal Status", "state_timeline", TIMELINE_COLUMNS, [("Nav", 0, "IDLE"), ("Nav", 10**9, "ACTIVE")])
    table = render("Calibration", "table", [("Metric", "varchar"), ("Value", "varchar")], [("Total Samples", "300")])
    scalar = render("Time to goal", "scalar", [("_col0", "double")], [(41.25,)], units="s")
    image = render("Camera", "image", [("filename", "varchar")], [("cam.gif",), ("lost.gif",)], logs_dir=tmp_path)
    sections = [
        (
            "Job 1",
            [
                ("Robot Speed", line, {"status": "PASSED", "description": "Robot speed over time"}),
                ("Goal Status", timeline, {"status": "WARNING"}),
                ("Calibration", table, {"status": "PASSED"}),
                ("Time to goal", scalar, {"status": "BLOCKER", "units": "s", "description": "Time to reach the goal"}),
                ("Camera", image, {"status": "PASSED"}),
            ],
        ),
        (
            "Batch",
            [
                ("Max Error", bar, {"status": "PASSED"}),
                (
                    "Broken",
                    None,
                    {"status": "ERROR", "error": "line 1, column 8: Column 'speedd' cannot be resolved <x>"},
                ),
                ("Skipped", None, {"status": "NOT_RUN"}),
            ],
        ),
    ]
    page = report_html("Batch 42 report", sections)
    assert page.count(PLOTLYJS_HEAD) == 1
    assert not NETWORK_SCRIPT.search(page)
    assert [data[0]["type"] for data, _ in plots_in(page)] == ["scatter", "bar", "bar"]
    assert "<th>Metric</th><th>Value</th>" in page and "<td>Total Samples</td>" in page
    assert '<div class="lg-scalar">41.25 s</div>' in page
    assert page.count('<img src="data:image/gif;base64,') == 1 and "lost.gif: missing" in page
    assert "Column &#x27;speedd&#x27; cannot be resolved &lt;x&gt;" in page
    assert "Robot speed over time" in page and "Units: s" in page
    for status, count in {"PASSED": 4, "WARNING": 1, "BLOCKER": 1, "ERROR": 1, "NOT_RUN": 1}.items():
        assert page.count(f">{status}</span>") == count + 1  # each metric's badge plus the summary


def test_report_rejects_an_unknown_status():
    scalar = render("M", "scalar", [("c", "bigint")], [(1,)])
    with pytest.raises(ValueError, match="unknown metric status 'FINE'"):
        report_html("r", [("s", [("M", scalar, {"status": "FINE"})])])


def test_report_without_charts_has_no_plotlyjs():
    scalar = render("M", "scalar", [("c", "bigint")], [(1,)])
    page = report_html("r", [("s", [("M", scalar, {"status": "PASSED"})])])
    assert PLOTLYJS_HEAD not in page and "<script" not in page


def test_bar_of_two_columns_is_one_unnamed_series():
    """SignalFlag 1.8.0's demo config session.resim.yml draws [x, y] bars (12 of them)."""
    rows = [("dock", 3), ("charge", 5), ("dock", 2)]
    rendered = render("M", "bar", [("Phase", "varchar"), ("Count", "bigint")], rows)
    (trace,) = rendered.figure["data"]
    assert (trace["name"], trace["x"], trace["y"]) == ("", ["dock", "charge", "dock"], [3, 5, 2])
    layout = rendered.figure["layout"]
    assert (layout["xaxis"]["title"]["text"], layout["yaxis"]["title"]["text"]) == ("Phase", "Count")
    assert "meta" not in layout


def test_link_path_is_an_optional_last_column_of_bar_and_line():
    """ReSim documents an optional 4th link_path column for bars; its values follow each point."""
    columns = [("build", "varchar"), ("day", "bigint"), ("value", "double"), ("link_path", "varchar")]
    rows = [("1.4", 1, 2.0, "b1"), ("1.5", 1, 3.0, "b2"), ("1.4", 2, 4.0, "b3")]
    for template in ("bar", "line"):
        rendered = render("M", template, columns, rows)
        assert [(t["name"], plain(t["x"]), plain(t["y"])) for t in rendered.figure["data"]] == [
            ("1.4", [1, 2], [2.0, 4.0]),
            ("1.5", [1], [3.0]),
        ]
        assert rendered.figure["layout"]["meta"] == {"link_path": [["b1", "b3"], ["b2"]]}
    two = render("M", "bar", [("x", "varchar"), ("y", "bigint"), ("LINK_PATH", "varchar")], [("a", 1, "b1/j1")])
    assert (two.figure["data"][0]["x"], two.figure["layout"]["meta"]) == (["a"], {"link_path": [["b1/j1"]]})
