"""``python -m ctmm`` = the ``ctmm`` command."""
import sys

from .cli import main

sys.exit(main())
