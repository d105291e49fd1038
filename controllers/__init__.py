"""Controller side of simpro-sim: kinematics, joint loops, task-space loop, cueing.

Imports only numpy, scipy and python-control, never MuJoCo, so that the
same code can run on the rig's control computer.

Each name is imported from the submodule that defines it
(``from controllers.kinematics import inverse_kinematics``): ``import
controllers.errors`` (what the command line needs to start) costs nothing, and
``scipy.signal``, which the cueing filters need, alone takes seconds to import
on a loaded machine.
"""
