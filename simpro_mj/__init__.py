"""simpro-sim: an open co-simulation of the SIMPRO 3-DOF pneumatic motion platform.

The Python API (:mod:`simpro_mj.api`)::

    import simpro_mj as s
    r = s.run("step_pitch", {"duration_s": 2})
    r.metrics["axes"]["pitch"], r.columns["pitch_rad"], r.to_frame()
    s.compare("step_all")                 # {"joint_only": Result, "task_space": Result}
    s.load("step_pitch")                  # the resolved scenario
    s.shipped_scenarios()

``import simpro_mj`` is light: MuJoCo is imported when a plant is built.
"""

__version__ = "0.1.0"

__all__ = [
    "__version__",
    "run",
    "compare",
    "load",
    "Result",
    "shipped_scenarios",
    "UserInputError",
]

_API = {
    "run": "api",
    "compare": "api",
    "load": "api",
    "Result": "api",
    "shipped_scenarios": "config.scenario",
    "UserInputError": "core.errors",
}


def __getattr__(name: str):
    """Lazy exports (PEP 562): the API's modules import MuJoCo, this one does not."""
    if name in _API:
        import importlib

        return getattr(importlib.import_module(f".{_API[name]}", __name__), name)
    raise AttributeError(f"module 'simpro_mj' has no attribute {name!r}")


def __dir__():
    return sorted(__all__)
