"""Launch the gyro platform node.

    ros2 launch gyro_platform platform.launch.py [params_file:=FILE] [scene:=NAME|FILE]
        [input_topic:=/imu/data] [input_type:=imu|twist|twist_stamped] [use_sim_time:=true]
        [namespace:=robot1]

``params_file`` defaults to the package's ``config/platform.yaml``. ``scene``, ``input_topic``
and ``input_type`` override the params file only when given (an empty value keeps the file's);
``input_topic`` sets both ``imu_topic`` and ``twist_topic`` (only the one of the input type is
used). Replaying a bag: ``ros2 bag play BAG --clock`` with ``use_sim_time:=true``.
"""
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, OpaqueFunction
from launch.substitutions import LaunchConfiguration, PathJoinSubstitution
from launch_ros.actions import Node
from launch_ros.substitutions import FindPackageShare

ARGUMENTS = (
    ("params_file", PathJoinSubstitution([FindPackageShare("gyro_platform"), "config", "platform.yaml"]),
     "parameters file of the node"),
    ("scene", "", "scene file or name in config/scenes (coning, default …) giving the model defaults; "
                  "empty: the params file's"),
    ("input_topic", "", "input topic (Imu or Twist/TwistStamped); empty: the params file's"),
    ("input_type", "", "imu, twist or twist_stamped; empty: the params file's"),
    ("use_sim_time", "false", "use /clock (true when replaying a bag with 'ros2 bag play --clock')"),
    ("namespace", "", "namespace of the node and its topics"),
)


def _node(context, *args, **kwargs):
    """The node, with only the overrides that were given (evaluated at launch time)."""
    cfg = {name: LaunchConfiguration(name).perform(context) for name, _, _ in ARGUMENTS}
    overrides = {"use_sim_time": cfg["use_sim_time"].strip().lower() in ("true", "1", "yes", "on")}
    if cfg["scene"]:
        overrides["scene"] = cfg["scene"]
    if cfg["input_type"]:
        overrides["input_type"] = cfg["input_type"]
    if cfg["input_topic"]:
        overrides["imu_topic"] = cfg["input_topic"]
        overrides["twist_topic"] = cfg["input_topic"]
    parameters = ([cfg["params_file"]] if cfg["params_file"] else []) + [overrides]
    return [Node(package="gyro_platform", executable="platform_node", name="gyro_platform_node",
                 namespace=cfg["namespace"] or None, parameters=parameters, output="screen", emulate_tty=True)]


def generate_launch_description():
    return LaunchDescription(
        [DeclareLaunchArgument(name, default_value=default, description=desc) for name, default, desc in ARGUMENTS]
        + [OpaqueFunction(function=_node)])
