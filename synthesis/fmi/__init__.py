"""FMI plumbing: closed loops of a plant FMU and a controller FMU (fmpy master, container FMU),
composing FMUs (container FMUs, SSP files, defaults, units), law files and native C FMUs,
other FMI hosts."""
