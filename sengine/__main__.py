"""``python -m sengine``: the ``sengine`` command."""

import sys

from .cli import main

sys.exit(main())
