"""Real ROS 2 message definitions, as `ros2 bag record` stores them, for tests that write MCAP bags."""

from __future__ import annotations

# (dependencies after '=' separator lines)
_SEP = "=" * 80
HEADER_DEFS = f"""{_SEP}
MSG: std_msgs/Header
builtin_interfaces/Time stamp
string frame_id
{_SEP}
MSG: builtin_interfaces/Time
int32 sec
uint32 nanosec
"""
JOINT_STATE_DEF = """std_msgs/Header header
string[] name
float64[] position
float64[] velocity
float64[] effort
""" + HEADER_DEFS
ODOMETRY_DEF = f"""std_msgs/Header header
string child_frame_id
geometry_msgs/PoseWithCovariance pose
geometry_msgs/TwistWithCovariance twist
{_SEP}
MSG: geometry_msgs/PoseWithCovariance
Pose pose
float64[36] covariance
{_SEP}
MSG: geometry_msgs/Pose
Point position
Quaternion orientation
{_SEP}
MSG: geometry_msgs/Point
float64 x
float64 y
float64 z
{_SEP}
MSG: geometry_msgs/Quaternion
float64 x 0
float64 y 0
float64 z 0
float64 w 1
{_SEP}
MSG: geometry_msgs/TwistWithCovariance
Twist twist
float64[36] covariance
{_SEP}
MSG: geometry_msgs/Twist
Vector3 linear
Vector3 angular
{_SEP}
MSG: geometry_msgs/Vector3
float64 x
float64 y
float64 z
""" + HEADER_DEFS
