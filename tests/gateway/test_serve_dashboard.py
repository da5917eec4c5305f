"""`lakegate serve` serves the dashboard beside the SQL endpoint, for every branch and batch of the lake."""
from __future__ import annotations

import json
import urllib.request


def _get(url: str) -> tuple[int, bytes]:
    with urllib.request.urlopen(url, timeout=30) as response:
        return response.status, response.read()


def test_serve_mounts_the_dashboard_page_and_its_lake_listing(lake_server):
    status, page = _get(f"{lake_server.url}/dashboard/")
    assert status == 200 and b"<html" in page.lower()

    status, body = _get(f"{lake_server.url}/dashboard/api/lake")
    listing = json.loads(body)
    text = json.dumps(listing)
    assert status == 200
    assert '"main"' in text and '"b1"' in text and '"b2"' in text

    status, script = _get(f"{lake_server.url}/dashboard/static/plotly.min.js")
    assert status == 200 and len(script) > 1_000_000
