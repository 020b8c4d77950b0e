"""The run machinery of a synthesis: the one run loop, the run folder (spec, checkpoints,
results), evaluation rules and backends (in-process, process pool, Dask), signals and the disk
guard."""
