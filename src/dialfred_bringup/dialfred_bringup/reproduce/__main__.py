"""`python -m dialfred_bringup.reproduce` (`./dialfred reproduce`)."""

import sys

from . import main

sys.exit(main())
