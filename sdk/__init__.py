"""SignalFlag's SDK (`signalflag.sdk`) against a local lake: `Batch` and `Test` (see their modules).

from lakegate.sdk import Batch, Test
"""

from lakegate.sdk.batch import Batch, FailedStatesError
from lakegate.sdk.test import Test

__all__ = ["Batch", "FailedStatesError", "Test"]
