"""``python -m rapid_cosim.cli``."""

import sys

from .main import main

sys.exit(main())
