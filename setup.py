"""Build glue: the top-level data folders go into the package.

``models/`` and ``scenarios/`` (with ``telemetry/``, ``presets/`` and ``rigs/``) sit at
the repository's top level; the wheel carries them as ``simpro_mj/models``
and ``simpro_mj/scenarios`` (:mod:`simpro_mj.core.shipped` finds either).
Everything else is in ``pyproject.toml``.
"""

from setuptools import find_packages, setup

#: package name in the wheel -> folder in the repository
DATA = {
    "simpro_mj.models": "models",
    "simpro_mj.scenarios": "scenarios",
    "simpro_mj.scenarios.telemetry": "scenarios/telemetry",
    "simpro_mj.scenarios.presets": "scenarios/presets",
    "simpro_mj.scenarios.rigs": "scenarios/rigs",
}

setup(
    packages=find_packages(include=["simpro_mj", "simpro_mj.*", "controllers", "controllers.*"])
    + list(DATA),
    package_dir=DATA,
    package_data={
        "simpro_mj.models": ["*.xml", "README.md"],
        "simpro_mj.scenarios": ["*.yaml"],
        "simpro_mj.scenarios.telemetry": ["*.csv"],
        "simpro_mj.scenarios.presets": ["*.yaml"],
        "simpro_mj.scenarios.rigs": ["*.yaml"],
    },
)
