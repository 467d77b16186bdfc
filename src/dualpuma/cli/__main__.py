"""``python -m dualpuma.cli``: the ``dualpuma`` command."""

import sys

from . import main

sys.exit(main())
