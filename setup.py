"""The compiled part of the package: the view search's whole-array passes (Cython + C).

Everything else is configured in pyproject.toml. The kernel is optional: where it cannot
be built (no C compiler, no Python headers) the install still succeeds with a warning and
the NumPy reference runs instead (:mod:`snapcore.select.kernels` chooses; the Makefile
installs gcc first, and ``tests/test_view_kernel.py`` fails where gcc is but the kernel
is not). ``-ffp-contract=off``: no fused multiply-adds, so the kernel's doubles are
NumPy's; ``-fno-math-errno``: ``sqrt`` as one (vectorisable) instruction, the same
correctly rounded result.
"""

from Cython.Build import cythonize
from setuptools import Extension, setup
from setuptools.command.build_ext import build_ext


class OptionalBuildExt(build_ext):
    """Build each extension if the compiler works, else warn and go on.

    setuptools' own ``optional=True`` is dropped by ``cythonize`` and does not cover a
    missing compiler executable (an OSError), so the failure is caught here.
    """

    def build_extension(self, ext):
        try:
            super().build_extension(ext)
        except Exception as exc:  # noqa: BLE001 - any build failure leaves the NumPy path
            self.warn(f"{ext.name} was not built ({exc}): the NumPy path will run instead")


setup(
    cmdclass={"build_ext": OptionalBuildExt},
    ext_modules=cythonize(
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
    ),
)
