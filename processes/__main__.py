"""`python -m processes` is `pingpong`."""
import sys

from processes import main

sys.exit(main())
