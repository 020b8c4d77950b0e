"""What a synthesis solves: the problem contract (flights -> objectives + constraints, budget),
problem files, their expressions, dispersion boxes."""
