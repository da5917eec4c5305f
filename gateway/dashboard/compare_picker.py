"""Picking two batches to compare by clicking two points of the trends page's charts.

Each chart's `plotly_click` picks the batch its point stands for: the batch its `link_path` value
names (`batch` or `batch/job`), else the batch its x (or label, or y) names, else, for a build's
point, the latest batch of that build among the page's batches. A second point of another batch
opens `/dashboard/compare/` with the earlier batch as the base. On this page a click on a linked
point picks it instead of opening the batch page (the batches table still links there). The form
of `Dashboard.compare_form` stays as the way without a chart.
"""

from __future__ import annotations

from collections.abc import Sequence

from lakegate.gateway.metrics.figures_html import script_json
from lakegate.gateway.metrics.trends import BatchInfo

_SCRIPT = """\
(function () {
  var branch = %(branch)s, batches = %(batches)s, picked = null;
  function find(value, byBuild) {
    if (value === undefined || value === null) { return -1; }
    var text = String(value), head = text.split("/")[0];
    for (var i = batches.length - 1; i >= 0; i--) {
      if (byBuild ? batches[i].builds.indexOf(text) >= 0 : batches[i].id === text || batches[i].id === head) {
        return i;
      }
    }
    return -1;
  }
  function batchOf(gd, point) {
    var meta = (gd.layout && gd.layout.meta) || {}, links = meta.link_path || [];
    var values = [(links[point.curveNumber] || [])[point.pointNumber], point.x, point.label, point.y];
    for (var pass = 0; pass < 2; pass++) {
      for (var v = 0; v < values.length; v++) {
        var found = find(values[v], pass === 1);
        if (found >= 0) { return found; }
      }
    }
    return -1;
  }
  function named(index) {
    var batch = batches[index];
    return batch.id + (batch.builds.length ? " (build " + batch.builds.join(", ") + ")" : "");
  }
  function tell(gd, text) {  // in the note above the charts, and under the chart clicked
    var here = document.getElementById("compare-picked") || document.createElement("p");
    here.id = "compare-picked";
    here.className = "lg-compare-pick";
    here.textContent = document.getElementById("compare-pick").textContent = text;
    gd.insertAdjacentElement("afterend", here);
  }
  function pick(gd, event) {
    var index = batchOf(gd, event.points[0]);
    if (index < 0) {
      tell(gd, "That point is neither a batch nor a build of the batches on this page: pick another.");
    } else if (picked === null || picked === index) {
      picked = index;
      tell(gd, "Picked " + named(index) + ": click a point of another batch to compare the two.");
    } else {
      var query = new URLSearchParams({
        branch: branch, base: batches[Math.min(picked, index)].id, batch: batches[Math.max(picked, index)].id
      });
      window.location.href = "/dashboard/compare/?" + query.toString();
    }
  }
  window.addEventListener("load", function () {
    document.querySelectorAll("[id^='lg-figure-']").forEach(function (gd) {
      if (typeof gd.on !== "function") { return; }
      gd.removeAllListeners("plotly_click");
      gd.on("plotly_click", function (event) { pick(gd, event); });
    });
  });
})();
"""


def compare_picker(branch: str, batches: Sequence[BatchInfo]) -> str:
    """The note and script that let a click on two chart points open the comparison of their batches
    (`batches`: the page's, in time order)."""
    data = [{"id": b.batch_id, "builds": list(b.builds)} for b in batches]
    script = _SCRIPT % {"branch": script_json(branch), "batches": script_json(data)}
    return (
        '<p id="compare-pick" class="lg-compare-pick">Or click a point of a chart, then a point of another '
        "batch: the two batches are compared (a build's point stands for its latest batch here).</p>\n"
        f"<script>\n{script}</script>\n"
    )
