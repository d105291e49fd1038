"""The plant: what the rig is made of. No controller, no scenario.

- :mod:`.model_params`, :mod:`.model`: the closed-chain MJCF (package data
  ``models/``), its parameters, loading, assembling and
  ``PhysicsError`` from ``data.warning``.
- :mod:`.pneumatics` (a package: params, flow law, nonlinear and linear
  actuators, statics, factory): valves and cylinders (eqs. 15-19).
- :mod:`.step_functions`: the plant's part of the 1 ms step (state read, sensor
  models, valves, chambers, forces) as plain functions, interpreted or compiled.
- :mod:`.kernels`: the ``SIMPRO_KERNEL`` switch (compiled step or interpreted).
- :mod:`.sensors`: potentiometers, height encoder, IMU (configuration).
- :mod:`.faults`: scheduled supply drops, stuck valves, sensor faults.
- :mod:`.payload`: statics shared by identification and the preflight.

Each part owns its parameter record and its defaults; the scenario (``config``)
is validated against them. Only :mod:`.model` and what builds on it (:mod:`.pneumatics.statics`,
:mod:`.pneumatics.factory`, :mod:`.payload`) import MuJoCo at import time.
"""
