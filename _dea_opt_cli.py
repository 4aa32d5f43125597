"""The ``dea-opt`` console script's entry point, outside the package on purpose.

``import dea_opt`` takes a third of a second (numpy, scipy, pandas); a Ctrl-C in that time would
end in Python's KeyboardInterrupt traceback, and nothing inside the package can catch it, since
the package is what is being imported. This module imports it under a handler.
"""

import sys


def entry() -> None:
    """Run :func:`dea_opt.cli.entry`; a Ctrl-C while dea-opt starts exits 130 with one line."""
    try:
        from dea_opt.cli import entry as dea_opt_entry
    except KeyboardInterrupt:
        sys.stderr.write("dea-opt: interrupted while starting; no output of this command was published\n")
        sys.exit(130)
    dea_opt_entry()
