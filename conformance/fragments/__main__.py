"""`python -m conformance.fragments --examples N`: fuzz the loader and print the throughput."""

import sys

from .fuzz import main

sys.exit(main())
