"""Build hook: the wheel ships the repository's ``configs/`` inside the package, as ``agents/configs/``.

Users of a source checkout copy and edit ``configs/train/*.yaml`` and ``configs/env/*.yaml`` where they are; an
installed wheel finds the same files by name (``pneunet-grasp train --config ppo``, ``demo --config
designed-kitchen``) through :mod:`agents.common.resources`. Everything else is declared in ``pyproject.toml``.
"""

import shutil
from pathlib import Path

from setuptools import setup
from setuptools.command.build_py import build_py

SHIPPED = ("train/*.yaml", "env/*.yaml", "env/*.best_ramp.json")


class BuildPyWithConfigs(build_py):
    def run(self) -> None:
        super().run()
        if getattr(self, "editable_mode", False):  # an editable install reads configs/ in place
            return
        root = Path(__file__).resolve().parent / "configs"
        dest = Path(self.build_lib) / "agents" / "configs"
        if not any(root.glob(SHIPPED[0])):  # an sdist without configs/ (MANIFEST.in grafts it) would ship none
            raise RuntimeError(f"no train configs in {root}: the wheel would ship no configs")
        for pattern in SHIPPED:
            for src in sorted(root.glob(pattern)):
                target = dest / src.relative_to(root)
                target.parent.mkdir(parents=True, exist_ok=True)
                shutil.copyfile(src, target)


setup(cmdclass={"build_py": BuildPyWithConfigs})
