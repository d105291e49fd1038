"""Plant side of simpro-sim: MuJoCo model, pneumatics, sensors, co-simulation."""

__version__ = "0.1.0"
