"""`template_settings` of a system template, the settings SignalFlag's configs use, applied to the Plotly figure:

    template_settings:
      xaxis: {label: Mission}              # the axis titles
      yaxis: {label: Speed (m/s), min: 0}  # min and max fix that end of the axis range
      display: {bins: 40}                  # a histogram's number of bins
      series:                              # a colour per series (the group_name of line and bar results)
        - {group_name: odometry, color: "#AE84DE"}

Any other key is listed by `unused_settings` (docs/resim-compat.md says which are not honoured).
"""

from __future__ import annotations

from typing import Any

#: The keys honoured, per section.
HONOURED = {"xaxis": {"label", "min", "max"}, "yaxis": {"label", "min", "max"}, "display": {"bins"}, "series": set()}


def apply_template_settings(figure: dict[str, Any] | None, settings: dict[str, Any]) -> None:
    """Change `figure` (a Plotly figure dict, in place) as `settings` say; nothing for a figureless result."""
    if figure is None or not isinstance(settings, dict):
        return
    layout = figure.setdefault("layout", {})
    for axis in ("xaxis", "yaxis"):
        options = settings.get(axis)
        if not isinstance(options, dict):
            continue
        target = layout.setdefault(axis, {})
        if options.get("label") is not None:
            title = target.get("title")
            target["title"] = {**(title if isinstance(title, dict) else {}), "text": str(options["label"])}
        low, high = options.get("min"), options.get("max")
        if low is not None or high is not None:
            target["range"] = [low, high]
            target["autorange"] = False if low is not None and high is not None else "max" if low is not None else "min"
    display = settings.get("display")
    if isinstance(display, dict) and isinstance(display.get("bins"), int):
        for trace in figure.get("data", []):
            if trace.get("type") == "histogram":
                trace["nbinsx"] = display["bins"]
    series = settings.get("series")
    if isinstance(series, list):
        colors = {
            str(s["group_name"]): s["color"]
            for s in series
            if isinstance(s, dict) and "group_name" in s and "color" in s
        }
        for trace in figure.get("data", []):
            color = colors.get(str(trace.get("name")))
            if color is not None:
                for part in ("marker", "line"):
                    trace.setdefault(part, {})["color"] = color


def unused_settings(settings: dict[str, Any]) -> list[str]:
    """The keys of `settings` lakegate does not honour (`section.key` or `section`)."""
    if not isinstance(settings, dict):
        return []
    unused = []
    for section, value in settings.items():
        if section not in HONOURED:
            unused.append(str(section))
        elif isinstance(value, dict):
            unused += [f"{section}.{key}" for key in value if key not in HONOURED[section]]
    return unused
