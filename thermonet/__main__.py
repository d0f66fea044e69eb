"""``python -m thermonet ...``: the same as the ``thermonet`` command."""

from .cli.main import main

raise SystemExit(main())
