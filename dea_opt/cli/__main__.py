"""``python -m dea_opt.cli``: the same as the ``dea-opt`` command."""

import sys

from . import main

sys.exit(main())
