"""``python -m hexsim.cli``: the ``hexsim`` command."""

import sys

from hexsim.cli import main

sys.exit(main())
