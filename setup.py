"""The compiled part of the package: the view search's whole-array passes (Cython + C).

Everything else is configured in pyproject.toml. The kernel is optional: on a machine
without a C compiler or Python's headers it is left out (with a message) and the NumPy
reference runs instead (:mod:`snapcore.select.kernels` chooses). The Makefile installs
gcc first, and ``tests/test_view_kernel.py`` fails where gcc is but the kernel is not.
A compile that fails with a compiler present fails the install: that is a bug to see.

``-ffp-contract=off``: no fused multiply-adds, so the kernel's doubles are NumPy's;
``-fno-math-errno``: ``sqrt`` as one (vectorisable) instruction, the same correctly
rounded result.
"""

import os
import shlex
import shutil
import sys
import sysconfig
from pathlib import Path

from setuptools import Extension, setup


def _can_compile() -> bool:
    """A C compiler (``$CC``, else the one Python was built with) and ``Python.h``."""
    cc = os.environ.get("CC") or sysconfig.get_config_var("CC") or "cc"
    found = shutil.which(shlex.split(cc)[0]) is not None
    headers = (Path(sysconfig.get_path("include")) / "Python.h").is_file()
    if not (found and headers):
        missing = "a C compiler" if not found else "Python's headers (Python.h)"
        print(
            f"setup.py: no {missing}: the view kernel is not built, NumPy runs instead",
            file=sys.stderr,
        )
    return found and headers


def _extensions() -> list:
    if not _can_compile():
        return []
    from Cython.Build import cythonize

    return cythonize(
        [
            Extension(
                "snapcore.select._pma_kernel",
                ["snapcore/select/_pma_kernel.pyx"],
                include_dirs=["snapcore/select"],  # _pma_core.h: the loops
                depends=["snapcore/select/_pma_core.h"],
                extra_compile_args=["-O3", "-ffp-contract=off", "-fno-math-errno"],
            )
        ],
        quiet=True,
    )


setup(ext_modules=_extensions())
