"""Compiled (numba) kernels, private to ea_gym: the domain modules call them, tests hold each one
against a plain numpy form of the same arithmetic. Nothing here is public API."""
