"""The synthesis core (methods, runs, problems, FMI, command line) and the systems built on it."""
