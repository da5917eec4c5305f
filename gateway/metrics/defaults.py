"""Default thresholds of trend alerts, flake detection and batch comparison: plain numbers, so the
command line's help shows them without importing the metrics engine."""

from __future__ import annotations

#: Trend alerts: default k (standard deviations) and number of earlier builds.
K, HISTORY = 3.0, 10
#: The default largest coefficient of variation of a scalar over runs of one build that is not flaky.
CV_THRESHOLD = 0.2
#: Default significance level of the two-sample tests.
ALPHA = 0.05
#: Default number of batches (up to the new one) in which flaky experiences are looked for.
FLAKE_WINDOW = 10
