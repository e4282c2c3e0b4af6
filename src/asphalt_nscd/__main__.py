"""``python -m asphalt_nscd``: the ``asphalt-nscd`` command."""

import sys

from .cli import main

sys.exit(main())
