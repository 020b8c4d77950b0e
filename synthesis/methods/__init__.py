"""General methods that know no system: the network operator and its variational GA, Pareto
utilities, the shooting method, the direct (Newton-Kantorovich) method, open-loop programs."""
