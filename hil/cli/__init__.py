"""The ``hil`` command: one module per subcommand, each exporting ``add_subparser``."""
