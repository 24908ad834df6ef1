"""The compiled part of the package: the view search's whole-array passes (Cython).

Everything else is configured in pyproject.toml. ``optional=True``: without a C compiler
the install still succeeds and the NumPy reference runs instead
(:mod:`snapcore.select.kernels` chooses); the Makefile installs gcc before it builds.
``-ffp-contract=off``: no fused multiply-adds, so the kernel's doubles are NumPy's;
``-fno-math-errno``: ``sqrt`` as one (vectorisable) instruction, the same correctly
rounded result.
"""

from Cython.Build import cythonize
from setuptools import Extension, setup

setup(
    ext_modules=cythonize(
        [
            Extension(
                "snapcore.select._pma_kernel",
                ["snapcore/select/_pma_kernel.pyx"],
                include_dirs=["snapcore/select"],  # _pma_core.h: the loops
                depends=["snapcore/select/_pma_core.h"],
                extra_compile_args=["-O3", "-ffp-contract=off", "-fno-math-errno"],
                optional=True,
            )
        ],
        quiet=True,
    )
)
