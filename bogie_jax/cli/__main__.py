"""`python -m bogie_jax.cli`: the `bogie-jax` command."""

import sys

from . import main


sys.exit(main())
