"""``python -m oracle.cli``: the ``raster-oracle`` command."""

import sys

from . import main

sys.exit(main())
