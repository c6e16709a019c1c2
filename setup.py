"""The one compiled part of chaplygin, built when the package is installed.

Every run of the ``c`` backend integrates with a DOP853 loop written in C
(:mod:`chaplygin.numeric._ckernel`), the same for every model: only the model's
``fill`` is compiled per system.  Built here, at install time, the loop is a file
of the installed package, and a first run after installation does not pay its
compilation (about 0.2 s).  Where no C compiler is found or it fails, the
installation goes on without it and the loop is built on first use into the
kernel cache, as before.  The rest of the metadata is in ``pyproject.toml``.
"""

from __future__ import annotations

import sys
from pathlib import Path

from setuptools import Extension, setup
from setuptools.command.build_ext import build_ext


class BuildLoop(build_ext):
    """Builds the loop library with chaplygin's own compiler command and flags (not the
    Python extension's: the library is loaded by :mod:`ctypes`, never imported)."""

    def build_extension(self, ext: Extension) -> None:
        sys.path.insert(0, str(Path(__file__).resolve().parent / "src"))
        try:
            from chaplygin.numeric import _ckernel

            _ckernel.install_loop(Path(self.get_ext_fullpath(ext.name)))
        except Exception as exc:  # no compiler, or it failed: the loop is built on first use
            print(
                f"chaplygin: the C loop library was not built at install time ({exc}); "
                "it is built on first use instead",
                file=sys.stderr,
            )
        finally:
            sys.path.pop(0)


setup(
    ext_modules=[Extension("chaplygin.numeric._dop853_loop", sources=[], optional=True)],
    cmdclass={"build_ext": BuildLoop},
)
