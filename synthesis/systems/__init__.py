"""One package per system (``synthesis/systems/<stem>/``): everything that system adds.

Each package defines ``SYSTEM``, a :class:`synthesis.registry.System` record; the registry
lists the stems.  Importing this package imports no system.
"""
