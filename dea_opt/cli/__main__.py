"""``python -m dea_opt.cli``: the same as the ``dea-opt`` command."""

from . import entry

entry()
