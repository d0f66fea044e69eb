"""The ``thermonet`` command: one module per subcommand, each with ``add_args`` and ``handle``."""
