"""`python -m madsim ...` is the `madsim` command."""

import sys

from madsim.cli import main

sys.exit(main())
