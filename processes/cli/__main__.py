"""`python -m processes.cli` is `pingpong`."""
import sys

from processes import main

sys.exit(main())
