"""Physics and simulators: closed loops (FOPDT + PI), valve friction models (data-driven
stiction, LuGre, Karnopp, deadband) and identification of valve friction parameters.
No I/O and no clock in this package."""
