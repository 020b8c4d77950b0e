"""The models: every system's equations, written once, and the FMU classes that wrap them."""
