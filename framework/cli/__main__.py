"""`python -m crashlab.cli ...`: the same as `crashlab ...`."""
import sys

from .main import main

sys.exit(main())
