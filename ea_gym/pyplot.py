"""matplotlib's pyplot on the Agg backend, chosen here once for every figure the project draws.

Every figure is written to a file (or rendered to an array), never shown: ``from ea_gym.pyplot import plt``.
"""

import matplotlib

matplotlib.use("Agg")
from matplotlib import pyplot as plt  # noqa: E402 - after the backend is chosen

__all__ = ["plt"]
