"""`python -m processes.cli` is `pingpong`."""
import sys

from processes.cli import main

sys.exit(main())
