"""The ``descent-fmus`` command line (entry point: :mod:`synthesis.cli.main`)."""
