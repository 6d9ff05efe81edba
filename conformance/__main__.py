import sys

from .extras import missing_harness

missing = missing_harness()
if missing:
    print(missing, file=sys.stderr)
    sys.exit(2)

from .cli import main  # after the check: the command line imports the harness's packages

sys.exit(main())
