"""``python -m workbench COMMAND ...``: the same as the ``workbench`` command."""

import sys

from .launch import main

sys.exit(main())
