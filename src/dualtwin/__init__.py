"""dualtwin: dual digital twins (Webots on ODE + MuJoCo) for robotics RL.

Importing the package does two light things, before any dualtwin module imports MuJoCo:

* picks a headless OpenGL backend for MuJoCo where there is no display (:mod:`dualtwin.headless`;
  :func:`gl_backend` says which and why);
* sends MuJoCo's warnings to stderr rather than a ``MUJOCO_LOG.TXT`` in the user's current folder
  (:func:`dualtwin.headless.route_mujoco_warnings`, applied when MuJoCo is imported);
* registers the ``dualtwin/...`` Gymnasium env ids when Gymnasium is installed (:mod:`dualtwin.registration`,
  entry-point strings only), so ``gym.make("dualtwin/CartPole-MuJoCo-v0")`` works after ``import dualtwin``
  (the ecosystem's idiom: ``gym.register_envs(dualtwin)``); without importing Gymnasium itself: the ids are
  registered as soon as the program imports it (the ``dualtwin`` command starts without paying for it).
"""

import sys

from dualtwin.errors import quiet_interrupts_in_cli

# ``python -m dualtwin.cli`` reads "-m" as argv[0] while the package imports: the original command line says more.
quiet_interrupts_in_cli(sys.argv[0] if sys.argv else "", getattr(sys, "orig_argv", []))
from dualtwin.interrupts import hold_while_loading  # noqa: E402 - after the interrupt hook

hold_while_loading(only_command_line=True)  # the command says what a Ctrl-C while it loads keeps

from dualtwin.headless import GLChoice, gl_backend, route_mujoco_warnings  # noqa: E402 - after the interrupt hook

__version__ = "0.1.0"

gl_backend()
route_mujoco_warnings()

from dualtwin.registration import register_envs, register_when_gymnasium_loads  # noqa: E402 - after the backend choice

register_when_gymnasium_loads()

__all__ = ["GLChoice", "__version__", "gl_backend", "register_envs"]
