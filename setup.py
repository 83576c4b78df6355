"""Build hook: ship the top-level `grammar/` and `stdlib/` inside the wheel.

The repository keeps them at the top level (where users and docs expect them); an installed
wheel must work outside the repository, so `build_py` copies them to `gnppdsl/data/`.
`gnppdsl.resources` looks there first and falls back to the source tree.
"""
from pathlib import Path
import shutil

from setuptools import setup
from setuptools.command.build_py import build_py


class BuildPyWithData(build_py):
    def run(self) -> None:
        super().run()
        root = Path(__file__).parent
        for name, pattern in (("grammar", "*.lark"), ("stdlib", "*.pntc")):
            target = Path(self.build_lib) / "gnppdsl" / "data" / name
            target.mkdir(parents=True, exist_ok=True)
            for src in sorted((root / name).glob(pattern)):
                shutil.copy2(src, target / src.name)


setup(cmdclass={"build_py": BuildPyWithData})
