"""``python -m cablekit.cli``: the ``cablekit`` command."""

from cablekit.cli import main

raise SystemExit(main())
