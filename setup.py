"""Build of the optional C LAMBDA kernels (``robustrtk/ambiguity/_lambda_c.c``).

All metadata is in pyproject.toml; this file only declares the extension. It is optional:
when it cannot be compiled (no compiler, no Python headers) the install goes on with a
warning, and the pure-Python references serve (algorithms.md §22).
"""

from __future__ import annotations

import sys

from setuptools import Extension, setup
from setuptools.command.build_ext import build_ext


class OptionalBuildExt(build_ext):
    """``build_ext`` that warns, instead of failing, when the C kernels cannot be built."""

    def run(self) -> None:
        try:
            super().run()
        except Exception as err:  # no compiler at all (DistutilsPlatformError and the like)
            self._warn(err)

    def build_extension(self, ext: Extension) -> None:
        if self.compiler.compiler_type == "msvc":
            ext.extra_compile_args = ["/O2", "/fp:precise"]
        else:
            # no contraction into fused multiply-adds, no fast-math: the kernels must give
            # the pure references' results bit for bit
            ext.extra_compile_args = ["-O2", "-std=c99", "-ffp-contract=off", "-fno-fast-math"]
            ext.libraries = ["m"]
        try:
            super().build_extension(ext)
        except Exception as err:  # CompileError, LinkError, a missing compiler executable
            self._warn(err)

    @staticmethod
    def _warn(err: Exception) -> None:
        print(
            f"WARNING: the optional C LAMBDA kernels were not built ({err}); "
            "the pure-Python references will be used",
            file=sys.stderr,
        )


setup(
    ext_modules=[
        Extension(
            "robustrtk.ambiguity._lambda_c",
            sources=["src/robustrtk/ambiguity/_lambda_c.c"],
            define_macros=[("RRTK_WITH_PYINIT", "1")],
            optional=True,
        )
    ],
    cmdclass={"build_ext": OptionalBuildExt},
)
