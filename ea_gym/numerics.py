"""Numerical constants shared by the modules."""

TINY = 1e-300
"""Smallest denominator (in the quantity's own SI unit): keeps a ratio finite where its denominator is an
exact zero (an element a window never excites) without biasing any denominator a real signal gives."""
