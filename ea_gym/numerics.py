"""Numerical constants shared by the modules."""

TINY = 1e-300
"""Smallest denominator (in the quantity's own SI unit): keeps a ratio finite where its denominator is an
exact zero (an element a window never excites) without biasing any denominator a real signal gives."""

MAX_SAMPLES = 1_000_000
"""Most samples one simulated run (a scenario, an environment step's window) may have: a run keeps a few dozen
float64 signals per sample (states, every bond's effort and flow, every element's power), about 250 MB at this
limit; checked before anything is allocated (10,000 s at 100 Hz)."""

MAX_LOAD = 1e9
"""Largest load value (the load source's unit, N, V, ...) a scenario may ask for: powers are products of two
signals, and squares of larger values leave float64's accurate range (1e300 overflowed to inf)."""

MAX_SINES = 1000
"""Most sines a scenario's load may sum."""

MAX_SINE_TERMS = 100_000_000
"""Most samples x sines a scenario's load may ask for (each a sine evaluated; about a second of work): 24,000 sines over
a run asked for 179 GiB at once."""
