"""`python -m reactive_anim ...`: see cli.py."""

import sys

from .cli import main

sys.exit(main())
