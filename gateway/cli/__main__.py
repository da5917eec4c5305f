"""`python -m lakegate.gateway.cli`: the `lakegate` command."""

import sys

from lakegate.gateway.cli.main import main

sys.exit(main())
