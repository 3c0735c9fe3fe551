"""``python -m hexsim``: the ``hexsim`` command."""

import sys

from hexsim.cli import main

sys.exit(main())
