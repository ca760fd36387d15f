"""``python -m drake_uuv.cli``: the same as the ``drake-uuv`` command."""

import sys

from drake_uuv.cli import main

if __name__ == "__main__":
    sys.exit(main())
