"""``python -m pickstop.cli``: the ``pickstop`` command."""

import sys

from pickstop.cli import main

sys.exit(main())
