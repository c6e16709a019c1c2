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

#: the loop library's module name in the package; its record (key and SHA-256) is LOOP.json beside it
LOOP = "_dop853_loop"


class BuildLoop(build_ext):
    """Builds the loop library with chaplygin's own compiler command and flags (not the
    Python extension's: the library is loaded by :mod:`ctypes`, never imported)."""

    def build_extension(self, ext: Extension) -> None:
        out = Path(self.get_ext_fullpath(ext.name))
        for old in out.parent.glob(f"{LOOP}.*"):  # (a failed build ships no earlier one)
            old.unlink()
        sys.path.insert(0, str(Path(__file__).resolve().parent / "src"))
        try:
            from chaplygin.numeric import _ckernel

            _ckernel.install_loop(out)
        except Exception as exc:  # no compiler, or it failed: the loop is built on first use
            print(
                f"chaplygin: the C loop library was not built at install time ({exc}); "
                "it is built on first use instead",
                file=sys.stderr,
            )
        finally:
            sys.path.pop(0)

    def get_outputs(self) -> list[str]:
        """The library and its record (``LOOP.json``: the key and bytes it was built with)."""
        outputs = super().get_outputs()
        return outputs + [str(Path(o).with_name(f"{LOOP}.json")) for o in outputs]

    def copy_extensions_to_source(self) -> None:
        """An editable install's copy into the source tree: the record too, if it was built."""
        super().copy_extensions_to_source()
        build_py = self.get_finalized_command("build_py")
        for ext in self.extensions:
            built = Path(self.build_lib, self.get_ext_filename(self.get_ext_fullname(ext.name)))
            record = built.with_name(f"{LOOP}.json")
            target = Path(build_py.get_package_dir(ext.name.rpartition(".")[0]), record.name)
            target.unlink(missing_ok=True)
            if record.exists():
                self.copy_file(str(record), str(target), level=self.verbose)


setup(
    ext_modules=[Extension(f"chaplygin.numeric.{LOOP}", sources=[], optional=True)],
    cmdclass={"build_ext": BuildLoop},
)
