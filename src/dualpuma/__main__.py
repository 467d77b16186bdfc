"""``python -m dualpuma``: the ``dualpuma`` command (as ``python -m dualpuma.cli``)."""

import sys

from .cli import main

sys.exit(main())
