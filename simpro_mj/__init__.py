"""simpro-sim: an open co-simulation of the SIMPRO 3-DOF pneumatic motion platform.

The Python API (:mod:`simpro_mj.api`)::

    import simpro_mj as s
    r = s.run("step_pitch", {"duration_s": 2})
    r.metrics["axes"]["pitch"], r.columns["pitch_rad"], r.to_frame()
    s.compare("step_all")                 # {"joint_only": Result, "task_space": Result}
    s.load_scenario("step_pitch")         # the resolved, typed Scenario (also s.load)
    r.plot("task_space")                  # a matplotlib Figure (Fig. 16)
    s.sweep("sweep_outer_gain", jobs=2)   # every variant of a sweep file
    s.shipped_scenarios()

``import simpro_mj`` is light: MuJoCo is imported when a plant is built.
"""

__version__ = "0.1.0"

_API = {
    "run": "api",
    "compare": "api",
    "load": "api",
    "load_scenario": "api",
    "sweep": "api",
    "Result": "api",
    "SweepResult": "api",
    "shipped_scenarios": "config.scenario",
    "UserInputError": "core.errors",
    "SweepError": "core.errors",
}

__all__ = ["__version__", *_API]


def __getattr__(name: str):
    """Lazy exports (PEP 562): the API's modules import MuJoCo, this one does not."""
    if name in _API:
        import importlib

        return getattr(importlib.import_module(f".{_API[name]}", __name__), name)
    raise AttributeError(f"module 'simpro_mj' has no attribute {name!r}")


def __dir__():
    return sorted(__all__)
