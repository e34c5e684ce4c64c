"""What the experiments' scripts share: the machine they ran on, and their ``--smoke`` mode.

The scripts import it as ``experiments.common`` after putting the checkout's root on ``sys.path``.
"""

from __future__ import annotations

import argparse
import os
import platform
import tempfile
from collections.abc import Mapping, Sequence
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path
from typing import Any

PACKAGES = ("numpy", "scipy", "numba", "torch", "gymnasium", "stable-baselines3")
#: the checkout's root: ea_gym, agents and experiments sit in it
ROOT = Path(__file__).resolve().parents[1]
SMOKE_HELP = ("the same run end to end on tiny sizes, in seconds (what CI runs); its outputs go to a fresh "
              "temporary folder unless --out names one, never over the committed results")


def machine_info() -> dict[str, Any]:
    """Processor, cores, platform, package versions, BLAS thread variables and the load average."""
    versions: dict[str, str | None] = {}
    for package in PACKAGES:
        try:
            versions[package] = version(package)
        except PackageNotFoundError:
            versions[package] = None
    return {
        "processor": platform.processor() or platform.machine(),
        "cpu_count": os.cpu_count(),
        "platform": platform.platform(),
        "python": platform.python_version(),
        **versions,
        "blas_threads_env": {k: os.environ.get(k) for k in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")},
        "load_average": list(os.getloadavg()) if hasattr(os, "getloadavg") else None,
    }


def parse_with_smoke(parser: argparse.ArgumentParser, argv: Sequence[str] | None, smoke: Mapping[str, Any]) -> argparse.Namespace:
    """``parser``'s arguments and a ``--smoke`` flag. With ``--smoke``, ``smoke``'s values replace the
    defaults (the options given still win) and an ``--out`` left at its default (where the parser has one
    and ``smoke`` does not set it) becomes a fresh temporary folder."""
    parser.add_argument("--smoke", action="store_true", help=SMOKE_HELP)
    args = parser.parse_args(argv)
    if not args.smoke:
        return args
    committed_out = parser.get_default("out")
    parser.set_defaults(**smoke)
    args = parser.parse_args(argv)
    if "out" in vars(args) and "out" not in smoke and args.out == committed_out:
        args.out = Path(tempfile.mkdtemp(prefix="ea-gym-smoke-"))
    return args
