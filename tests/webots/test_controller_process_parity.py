"""A controller behaves the same run in its own process (the default, as Webots runs it) as run in a thread of the
runner (``isolation="threads"``, the real API classes): each test runs one script on one world in both modes and
asserts the same output and exit code, and what Webots' Python API says (webots-python-api.md)."""

from __future__ import annotations

from pathlib import Path

from tests.support.isolation_runs import assert_threads_print, run_in_both_modes

WORLD = """#VRML_SIM R2023b utf8
WorldInfo { basicTimeStep 8 }
DEF ME Robot {
  supervisor TRUE
  controller "probe"
  children [
    HingeJoint {
      jointParameters HingeJointParameters { axis 0 0 1 }
      device [ RotationalMotor { name "rm" } PositionSensor { name "ps" } ]
      endPoint Solid { translation 0.3 0 0 boundingObject Sphere { radius 0.05 } physics Physics { } }
    }
    GPS { name "gps" }
  ]
}
"""


def test_robot_devices_is_the_name_to_device_dict_of_getdevice(tmp_path: Path) -> None:
    """webots-python-api.md, Robot: ``devices`` is a plain attribute, name -> device object, filled once in
    __init__, and ``getDevice`` returns that same (cached) object. A controller process had no ``devices`` at all
    (only attributes of plain data or single API objects were copied to the child, not a dict of devices)."""
    script = """
        from controller import Robot
        robot = Robot()
        print(sorted(robot.devices))
        print(all(robot.devices[name] is robot.getDevice(name) for name in robot.devices))
        print(type(robot.devices["rm"]).__name__, robot.devices["gps"].getName())
    """
    runs = run_in_both_modes(tmp_path, WORLD, script, 0.016)
    expected = "['gps', 'ps', 'rm']\nTrue\nMotor gps\n"
    assert_threads_print(runs, expected)


CONTACT_WORLD = """#VRML_SIM R2023b utf8
WorldInfo { basicTimeStep 8 }
DEF FLOOR Solid { name "floor" boundingObject Plane { } }
DEF BALL Solid {
  translation 0 0 0.049
  boundingObject Sphere { radius 0.05 }
  physics Physics { }
}
Robot { supervisor TRUE controller "probe" }
"""


def test_a_value_getter_called_with_arguments_raises_pythons_type_error(tmp_path: Path) -> None:
    """ContactPoint.getPoint takes no argument (webots-python-api.md, ContactPoint: ``getPoint ()``): calling it
    with one is Python's own TypeError for the method. A controller process raised NotImplementedError ('not
    available in a controller process') instead."""
    script = """
        from controller import Supervisor
        sup = Supervisor()
        ball = sup.getFromDef("BALL")
        ball.enableContactPointsTracking(8)
        sup.step(8)
        sup.step(8)
        point = ball.getContactPoints()[0]
        for args in ((), (1,)):
            try:
                point.getNodeId(*args)
                print("ok")
            except Exception as exc:
                print(type(exc).__name__, exc)
    """
    runs = run_in_both_modes(tmp_path, CONTACT_WORLD, script, 0.032)
    # Python's words for a one-parameter method (self) given a second positional argument
    expected = "ok\nTypeError ContactPoint.getNodeId() takes 1 positional argument but 2 were given\n"
    assert_threads_print(runs, expected)


def test_two_handles_of_one_node_are_equal_and_print_the_node(tmp_path: Path) -> None:
    """Two Node handles of one scene node compare equal and hash alike (a set of them has one element), and a Node
    prints as the API's Node class writes it. In a controller process each call's handle was a proxy compared by
    identity (``getSelf() == getFromDef("ME")`` was False) and printed '<Node (controller proxy)>'."""
    script = """
        from controller import Supervisor
        sup = Supervisor()
        me, again = sup.getSelf(), sup.getFromDef("ME")
        print(me == again, me != again, len({me, again, sup.getFromId(me.getId())}), me == sup.getRoot())
        print(me, repr(again))
        print(sup.getRoot().getField("children") == sup.getRoot().getField("children"))
    """
    runs = run_in_both_modes(tmp_path, WORLD, script, 0.016)
    # the Robot node DEF ME, three handles of it; a Field (no __eq__ of its own in Webots' class) is equal to itself
    # only, and each getField call gives a new one
    expected = "True False 1 False\n<Node Robot 'ME'> <Node Robot 'ME'>\nFalse\n"
    assert_threads_print(runs, expected)


LIDAR_WORLD = """#VRML_SIM R2023b utf8
WorldInfo { basicTimeStep 8 }
Solid { translation 1 0 0 children [ Shape { geometry DEF WALL Box { size 0.1 10 10 } } ] boundingObject USE WALL }
Robot {
  controller "probe"
  children [ Lidar { name "lidar" horizontalResolution 4 fieldOfView 1 numberOfLayers 1 maxRange 5 } ]
}
"""


def test_value_objects_compare_and_print_as_the_api_classes(tmp_path: Path) -> None:
    """A LidarPoint compares (and hashes) by its data, and value objects print as the API classes write them
    (``LidarPoint(x=..., y=..., z=..., layer=..., time=...)``, the plain attributes of webots-python-api.md,
    LidarPoint). In a controller process two equal points compared by identity and every value object printed
    '<LidarPoint (controller proxy)>'."""
    script = """
        from controller import Robot
        robot = Robot()
        lidar = robot.getDevice("lidar")
        lidar.enable(8)
        lidar.enablePointCloud()
        robot.step(8)
        first, second = lidar.getPointCloud(), lidar.getPointCloud()
        print(first[0] == second[0], first[0] != second[0], len(set(first) | set(second)), first[0] == first[1])
        p = first[0]
        print(repr(p) == str(p) == f"LidarPoint(x={p.x}, y={p.y}, z={p.z}, layer={p.layer}, time={p.time})")
    """
    runs = run_in_both_modes(tmp_path, LIDAR_WORLD, script, 0.016)
    # every one of the 4 rays hits the wall 1 m ahead (fov 1 rad: rays within 0.5 rad of the axis), each at its
    # own point: the two reads of one step give 4 distinct points, equal ray by ray
    expected = "True False 4 False\nTrue\n"
    assert_threads_print(runs, expected)


LED_WORLD = """#VRML_SIM R2023b utf8
WorldInfo { basicTimeStep 8 }
Robot { controller "probe" children [ LED { name "led" color [ 1 0 0 ] } ] }
"""


def test_a_command_given_a_whole_number_beyond_a_c_int_raises_at_the_call(tmp_path: Path) -> None:
    """LED.set takes a C int (webots-python-api.md, shared semantics: integers go to C unchanged; ctypes refuses
    one beyond its range): ``led.value = 10**20`` raises TypeError at that line and the controller goes on. In a
    controller process the command was queued (an int is a type it buffers) and its error came out of the next
    call, the step: the script died there instead."""
    script = """
        from controller import Robot
        robot = Robot()
        led = robot.getDevice("led")
        for value in (10**20, -2**31 - 1):
            try:
                led.value = value
                print("set")
            except TypeError as exc:
                print("TypeError at the call")
        print("step", robot.step(8), led.get())
        led.set(1)
        print("step", robot.step(8), led.get())
    """
    runs = run_in_both_modes(tmp_path, LED_WORLD, script, 0.1)
    # both beyond [-2**31, 2**31 - 1]; then 1, within the LED's one colour, is taken
    expected = "TypeError at the call\nTypeError at the call\nstep 0 0\nstep 0 1\n"
    assert_threads_print(runs, expected)


def test_controller_stopped_is_a_system_exit_in_a_controller_process(tmp_path: Path) -> None:
    """``ControllerStopped`` (a dualtwin export: how the run ends a controller, as Webots' library ends the
    process) is a SystemExit, not an Exception: raised by the script, the controller ends quietly with status 0.
    In a controller process it was a plain Exception there: ``except Exception`` caught it, and raised it ended
    the controller with a traceback and status 1."""
    script = """
        from controller import ControllerStopped, Robot
        robot = Robot()
        robot.step(8)
        print(issubclass(ControllerStopped, SystemExit), issubclass(ControllerStopped, Exception))
        raise ControllerStopped
    """
    runs = run_in_both_modes(tmp_path, WORLD, script, 0.1)
    expected = "True False\n"
    assert_threads_print(runs, expected)


def test_an_error_escaping_the_script_prints_the_scripts_own_traceback(tmp_path: Path) -> None:
    """An exception the script lets through prints Python's traceback from the script's first frame, as
    ``python probe.py`` prints it where Webots starts the controller, and the controller's status is 1. A
    controller thread printed the runner's own frames (runner.py, runpy) first."""
    script = """from controller import Robot
robot = Robot()
robot.step(8)
raise ValueError("boom")
"""
    runs = run_in_both_modes(tmp_path, WORLD, script, 0.1)
    expected = ('Traceback (most recent call last):\n  File "<project>/controllers/probe/probe.py", line 4, in <module>\n'
                '    raise ValueError("boom")\nValueError: boom\n')
    assert runs["process"] == ("", expected, 1)
    assert runs["threads"] == runs["process"]


def test_the_scripts_streams_are_the_interpreters_own_kind(tmp_path: Path) -> None:
    """A controller's ``sys.stdout``/``sys.stderr`` are text streams as the interpreter makes them (Webots starts
    ``python probe.py`` with its output on a pipe): a name, a descriptor, a byte layer (``buffer``), and they are
    ``sys.__stdout__``/``sys.__stderr__``. A controller process had a bare text object: no ``name``, no ``buffer``
    (``sys.stdout.buffer.write`` raised AttributeError), ``fileno()`` unsupported, and ``sys.__stdout__`` was the
    interpreter's first stream, whose output bypassed the ordered channel."""
    script = """
        import sys
        from controller import Robot
        robot = Robot()
        print(sys.stdout.name, sys.stderr.name, sys.stdout.fileno(), sys.stderr.fileno(),
              sys.__stdout__ is sys.stdout, sys.__stderr__ is sys.stderr, flush=True)
        sys.stdout.buffer.write("bytes \\u00e9\\n".encode(sys.stdout.encoding))
        sys.stdout.buffer.flush()
        print("to the original stderr", file=sys.__stderr__)
    """
    runs = run_in_both_modes(tmp_path, WORLD, script, 0.1)
    expected = "<stdout> <stderr> 1 2 True True\nbytes \u00e9\n"
    assert runs["threads"] == (expected, "to the original stderr\n", 0)
    assert runs["process"] == runs["threads"]


def test_api_classes_introspect_as_the_real_ones(tmp_path: Path) -> None:
    """What introspection reads of an API class in a controller process is what the real class says: its module,
    its methods' qualified names and annotated signatures, an instance's default text. A controller process said
    module 'controller', 'step' for ``Robot.step.__qualname__``, dropped the annotations, and printed a Field as
    '<Field (controller proxy)>'."""
    script = """
        import inspect
        from controller import Robot
        robot = Robot()
        motor = robot.getDevice("rm")
        print(Robot.__module__, type(motor).__module__, Robot.step.__qualname__, type(motor).setPosition.__qualname__)
        print(inspect.signature(Robot.step), inspect.signature(motor.setPosition))
        print(repr(robot))
    """
    runs = run_in_both_modes(tmp_path, WORLD, script, 0.1)
    # the API's modules (dualtwin.webots.robot: Robot; joint_devices: Motor) and its annotations, as written there
    expected = ("dualtwin.webots.robot dualtwin.webots.joint_devices Robot.step Motor.setPosition\n"
                "(self, time_step: 'Any' = None) -> 'int' (position: 'Any') -> 'None'\n"
                "<dualtwin.webots.robot.Robot object at 0x?>\n")
    assert_threads_print(runs, expected)


def test_an_argument_of_the_scripts_own_class_is_refused_by_the_api_not_the_channel(tmp_path: Path) -> None:
    """An argument the API does not take (an object of a class the script defines, a generator) is refused by the
    API in its own words, a TypeError at the call, and the controller goes on; a subclass of a plain type (an
    IntEnum) is its value. In a controller process an object of the script's class crashed the parent's serving
    thread ('Can't get attribute 'Angle' on <module '__main__'>'): the controller ended with status 1 and printed
    nothing more; a generator raised 'cannot pickle' instead of the API's TypeError."""
    script = """
        import enum
        from controller import Robot

        class Angle:
            def __repr__(self):
                return "Angle(0.5)"

        class Period(enum.IntEnum):
            BASIC = 8

        robot = Robot()
        motor, gps = robot.getDevice("rm"), robot.getDevice("gps")
        for value in (Angle(), (x for x in [1])):
            try:
                motor.setPosition(value)
            except TypeError as exc:
                print(exc)
        gps.enable(Period.BASIC)
        print(robot.step(8), gps.getSamplingPeriod(), motor.getTargetPosition())
    """
    runs = run_in_both_modes(tmp_path, WORLD, script, 0.1)
    # the API's words for a value that is not a number (api_args.as_float): the type's name and the value's text
    refusal = "Motor.setPosition() expects a number (a Python or NumPy scalar or a one-element array), got "
    expected = (f"{refusal}Angle Angle(0.5)\n{refusal}generator <generator object <genexpr> at 0x?>\n"
                "0 8 0.0\n")
    assert_threads_print(runs, expected)


CAMERA_WORLD = """#VRML_SIM R2023b utf8
WorldInfo { basicTimeStep 8 }
Robot { controller "probe" children [ Camera { name "cam" width 4 height 2 } ] }
"""


def test_an_error_of_a_class_the_script_does_not_know_is_still_its_built_in_kind(tmp_path: Path) -> None:
    """An error the API lets through from a library (here NumPy's UFuncTypeError, a TypeError, from
    ``Camera.imageGetGray`` given a NumPy width and text for a coordinate) is caught by ``except TypeError`` in a controller
    process as in a thread. The process made a class of that name derived from Exception only: ``except
    TypeError`` let it through and the controller died."""
    script = """
        import numpy as np
        from controller import Camera, Robot
        robot = Robot()
        image = bytes(4 * 4 * 2)
        try:
            Camera.imageGetGray(image, np.array([4]), "abc", 0)
            print("accepted")
        except TypeError as exc:
            print("TypeError", type(exc).__name__)
    """
    runs = run_in_both_modes(tmp_path, CAMERA_WORLD, script, 0.1)
    assert runs["threads"].code == 0 and runs["threads"].out.startswith("TypeError"), runs["threads"]
    assert runs["process"] == runs["threads"]


def test_value_objects_copy_pickle_and_go_back_to_the_api(tmp_path: Path) -> None:
    """Point-cloud points are plain data (webots-python-api.md, LidarPoint: plain attributes): a script may copy
    them, pickle them (to send them through an Emitter, to save them) and hand one back to an API call, which
    refuses it in its own words. In a controller process each of these raised the channel's internal
    '_HandleNeeded'."""
    script = """
        import copy, pickle
        from controller import Robot
        robot = Robot()
        lidar = robot.getDevice("lidar")
        lidar.enable(8)
        lidar.enablePointCloud()
        robot.step(8)
        cloud = lidar.getPointCloud()
        again = pickle.loads(pickle.dumps(cloud))
        print(again == cloud, copy.deepcopy(cloud[1]) == cloud[1], copy.copy(cloud[2]).x == cloud[2].x)
        print(type(again[0]).__name__, [round(p.x, 6) for p in again] == [round(p.x, 6) for p in cloud])
        try:
            lidar.enable(cloud[0])
        except TypeError as exc:
            print(exc)
    """
    runs = run_in_both_modes(tmp_path, LIDAR_WORLD, script, 0.1)
    # the copies are equal to the points (LidarPoint compares by its data); a point is not a sampling period: the
    # API's words (api_args.as_int), with the point's class and text
    refusal = "Lidar.enable() expects a number (a Python or NumPy scalar or a one-element array), got "
    point = runs["threads"].out.splitlines()[-1][len(refusal):]
    assert point.startswith("LidarPoint LidarPoint(x=") and point.endswith(")"), point
    expected = f"True True True\nLidarPoint True\n{refusal}{point}\n"
    assert_threads_print(runs, expected)


def test_an_error_crosses_with_its_arguments(tmp_path: Path) -> None:
    """An error the API raises keeps its ``args`` in a controller process: a KeyError (here from
    ``RangeFinder.rangeImageGetDepth`` given a dict for an image, indexed by the text the other arguments make)
    says its key as in a thread. The process raised KeyError with the key's text as the key ("'wx'" quoted twice)."""
    script = """
        from controller import RangeFinder, Robot
        robot = Robot()
        try:
            RangeFinder.rangeImageGetDepth({}, "w", "x", 1)
        except KeyError as exc:
            print(repr(exc), exc.args, exc)
    """
    runs = run_in_both_modes(tmp_path, WORLD, script, 0.1)
    # index y * width + x = 1 * "w" + "x" = "wx", not a key of the empty dict
    expected = "KeyError('wx') ('wx',) 'wx'\n"
    assert_threads_print(runs, expected)


def test_a_scripts_own_warning_prints_as_python_prints_it(tmp_path: Path) -> None:
    """A warning the script raises prints as its interpreter prints it where Webots starts ``python probe.py``
    (``file:line: Category: text`` and the source line), and an unclosed file's ResourceWarning stays silent (the
    interpreter's default filters), while the simulation's own warnings stay one ``Warning: ...`` line. A
    controller thread printed the script's warning as 'Warning: slow' and showed the ResourceWarning."""
    script = """import warnings
from controller import Supervisor
robot = Supervisor()
open(__file__)
warnings.warn("slow")
robot.getSelf().getField("translation").setSFVec3f([1, 2])
"""
    runs = run_in_both_modes(tmp_path, WORLD, script, 0.1)
    # Python's format for line 5 of the script; the Field's own refusal of a 2-vector for an SFVec3f
    expected = ('<project>/controllers/probe/probe.py:5: UserWarning: slow\n  warnings.warn("slow")\n'
                "Warning: Field.setSFVec3f(): new field value has wrong type or length ('translation'): ignored\n")
    assert runs["process"] == ("", expected, 0)
    assert runs["threads"] == runs["process"]


def test_a_numpy_object_that_does_not_pickle_is_refused_by_the_api(tmp_path: Path) -> None:
    """A NumPy object that is not data (an array's ``flat`` iterator) given where a number is expected is refused by
    the API in its own words, as in a thread; a NumPy scalar stays one (its type is named in the refusal). In a
    controller process the iterator raised 'cannot pickle 'numpy.flatiter' object'."""
    script = """
        import numpy as np
        from controller import Robot
        robot = Robot()
        motor = robot.getDevice("rm")
        for value in (np.arange(3).flat, np.str_("a")):
            try:
                motor.setPosition(value)
            except TypeError as exc:
                print(exc)
    """
    runs = run_in_both_modes(tmp_path, WORLD, script, 0.1)
    refusal = "Motor.setPosition() expects a number (a Python or NumPy scalar or a one-element array), got "
    expected = f"{refusal}flatiter <numpy.flatiter object at 0x?>\n{refusal}str_ np.str_('a')\n"
    assert_threads_print(runs, expected)


def test_a_step_given_an_object_of_the_scripts_class_is_refused_at_the_call(tmp_path: Path) -> None:
    """``step`` too refuses, in the API's words, an argument the parent cannot rebuild (the step goes its own way to
    the parent): in a controller process an object of the script's class crashed the parent's serving thread."""
    script = """
        from controller import Robot

        class Period:
            def __repr__(self):
                return "Period()"

        robot = Robot()
        try:
            robot.step(Period())
        except TypeError as exc:
            print(exc)
        print(robot.step(8))
    """
    runs = run_in_both_modes(tmp_path, WORLD, script, 0.1)
    assert runs["threads"].code == 0 and runs["threads"].out.endswith("Period Period()\n0\n"), runs["threads"]
    assert runs["process"] == runs["threads"]


def test_a_container_holding_an_object_of_the_scripts_class_is_refused_by_the_api(tmp_path: Path) -> None:
    """A container other than a tuple, list or dict (a set, a deque, a NumPy array of objects) holding an object of
    the script's own class is refused by the API in its own words, as in a thread. In a controller process such an
    argument pickled in the child (by reference to the script's class) and crashed the parent's serving thread
    ("Can't get attribute 'Angle' on <module '__main__'>"): the controller ended with status 1, its output lost."""
    script = """
        import collections
        import numpy as np
        from controller import Robot

        class Angle:
            def __repr__(self):
                return "Angle(0.5)"

        robot = Robot()
        motor = robot.getDevice("rm")
        for value in ({Angle()}, collections.deque([Angle()]), np.array([Angle()], dtype=object)):
            try:
                motor.setPosition(value)
            except TypeError as exc:
                print(exc)
        print(robot.step(8))
    """
    runs = run_in_both_modes(tmp_path, WORLD, script, 0.1)
    # the API's words (api_args.as_float): the type's name and the value's text; an array by its shape and dtype
    refusal = "Motor.setPosition() expects a number (a Python or NumPy scalar or a one-element array), got "
    expected = (f"{refusal}set {{Angle(0.5)}}\n{refusal}deque deque([Angle(0.5)])\n"
                f"{refusal}a NumPy array of shape (1,) and dtype object\n0\n")
    assert_threads_print(runs, expected)
