"""`python -m conformance.fragments --examples N`: fuzz the loader and print the throughput."""

import sys

from .fuzz import main

if __name__ == "__main__":  # worker processes import this module again (multiprocessing's spawn)
    sys.exit(main())
