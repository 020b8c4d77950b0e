"""The controller FMUs: the generic network-operator and program-table controllers, and the
systems' own."""
