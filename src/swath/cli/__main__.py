"""``python -m swath.cli``: the same as the ``swath`` command."""

import sys

from .main import main

sys.exit(main())
