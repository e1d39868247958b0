"""The build step that puts the default input files into the package.

topologies/, placements/ and traces/ sit at the checkout's root, where users edit them and
where the docs point. A built wheel must carry them too, so that an installed ``yafs-safetail``
runs without the checkout: this step copies the files yafs_safetail/defaults.py lists
(``DATA_FILES``), and the lock of library versions (``LOCK_FILE_NAME``), into the built package
as ``yafs_safetail/_data/``, where defaults.py looks first. An editable install reads them
from the checkout instead. Everything else is in setup.cfg.
"""

import runpy
import shutil
from pathlib import Path

from setuptools import setup
from setuptools.command.build_py import build_py

ROOT = Path(__file__).resolve().parent


class BuildPyWithDefaultFiles(build_py):
    """setuptools' build_py, then the default files copied into the built package."""

    def run(self) -> None:
        super().run()
        if getattr(self, "editable_mode", False):  # the package reads the checkout's own files
            return
        # defaults.py read as a file: the build must not import the package (or NumPy).
        defaults = runpy.run_path(str(ROOT / "yafs_safetail" / "defaults.py"))
        data_files = defaults["DATA_FILES"]
        target = Path(self.build_lib) / "yafs_safetail" / "_data"
        for folder, patterns in data_files.items():
            for pattern in patterns:
                for source in sorted((ROOT / folder).glob(pattern)):
                    copy = target / folder / source.relative_to(ROOT / folder)
                    copy.parent.mkdir(parents=True, exist_ok=True)
                    shutil.copyfile(source, copy)
        shutil.copyfile(ROOT / defaults["LOCK_FILE_NAME"], target / defaults["LOCK_FILE_NAME"])


setup(cmdclass={"build_py": BuildPyWithDefaultFiles})
