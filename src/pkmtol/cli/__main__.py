"""``python -m pkmtol.cli``: the same as the ``pkmtol`` command."""

import sys

from pkmtol.cli import main

sys.exit(main())
