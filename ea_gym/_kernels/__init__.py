"""Compiled (numba) kernels, private to ea_gym: the domain modules call them. Nothing here is public API.

Each kernel's specification is a plain-numpy function beside it: for ``ea_gym._kernels.<module>.<name>``,
``ea_gym._kernels.reference.<module>.<name>``, same signature, same effect (``ea_gym._kernels.reference``
states the rule and the few exemptions). Kernels that take many arguments take them in named records
(``typing.NamedTuple``, which numba types as named tuples): a filter bank's arrays, its settings, a step's
signals, its outputs. The hot entry points (``tracking.track``, ``monitor.monitor_chunk``) pass them into
compiled code as plain tuples, which numba types in C (a named tuple costs ~0.1 us a field, in Python).
"""
