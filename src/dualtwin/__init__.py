"""dualtwin: dual digital twins (Webots on ODE + MuJoCo) for robotics RL."""

__version__ = "0.1.0"
