"""Model descriptions: what every FMU builder and every closed loop read or write in
``modelDescription.xml`` -- the units of the variables (:mod:`.units`) and the declared start
values (:mod:`.declared`).  It imports nothing else of the package, so the native builders and
the closed loops both stand on it without importing each other."""
