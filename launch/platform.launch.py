# Copyright 2026 gyro_platform developers
#
# Licensed under the Apache License, Version 2.0 (the "License");
# you may not use this file except in compliance with the License.
# You may obtain a copy of the License at
#
#     http://www.apache.org/licenses/LICENSE-2.0
#
# Unless required by applicable law or agreed to in writing, software
# distributed under the License is distributed on an "AS IS" BASIS,
# WITHOUT WARRANTIES OR CONDITIONS OF ANY KIND, either express or implied.
# See the License for the specific language governing permissions and
# limitations under the License.

"""Launch the gyro platform node and robot_state_publisher.

    ros2 launch gyro_platform platform.launch.py [params_file:=FILE] [scene:=NAME|FILE]
        [input_topic:=/imu/data] [input_type:=imu|twist|twist_stamped] [output_rate:=HZ]
        [use_sim_time:=true] [namespace:=robot1] [frame_prefix:=robot1/] [log_level:=debug]
        [robot_state_publisher:=false]

``params_file`` defaults to the package's ``config/platform.yaml``. ``scene``, ``input_topic``,
``input_type`` and ``output_rate`` override the params file only when given (an empty value
keeps the file's); ``input_topic`` sets both ``imu_topic`` and ``twist_topic`` (only the one of
the input type is used). ``frame_prefix`` defaults to ``<namespace>/`` when a namespace is given
(``frame_prefix:=/`` for none). robot_state_publisher gets the URDF of the same parameters
(``gyro_platform.ros.urdf``) and the node's ``gimbal/joint_states``, and publishes
``/robot_description``, ``/tf`` and ``/tf_static``. Replaying a bag: ``ros2 bag play BAG --clock``
with ``use_sim_time:=true``. What is started is computed by ``gyro_platform.ros.launch_setup.plan``.
"""
from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, OpaqueFunction
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node

from gyro_platform.ros.launch_setup import ARGUMENTS, plan


class LaunchNotStarted(RuntimeError):
    """Bad launch arguments or parameters: nothing started (launch exits 1, one ERROR line)."""


def _nodes(context, *args, **kwargs):
    """The node (and robot_state_publisher), from the argument values at launch time."""
    values = {name: LaunchConfiguration(name).perform(context) for name, _, _ in ARGUMENTS}
    default_params = get_package_share_directory("gyro_platform") + "/config/platform.yaml"
    try:
        p = plan(values, default_params)
    except ValueError as e:            # LaunchArgumentError / ConfigError
        # launch logs an exception raised here as one ERROR line (its traceback at debug level)
        # and exits 1: an including bringup fails visibly instead of running without the platform
        raise LaunchNotStarted(f"gyro_platform: not started: {e}") from None
    actions = [Node(package="gyro_platform", executable="platform_node", name="gyro_platform_node",
                    namespace=p.namespace, parameters=p.node_parameters, arguments=["--ros-args", *p.ros_arguments],
                    output="screen", emulate_tty=True)]
    if p.rsp_parameters is not None:
        actions.append(Node(package="robot_state_publisher", executable="robot_state_publisher",
                            name="robot_state_publisher", namespace=p.namespace, parameters=[p.rsp_parameters],
                            remappings=p.rsp_remappings, arguments=["--ros-args", *p.ros_arguments],
                            output="screen"))
    return actions


def generate_launch_description():
    return LaunchDescription(
        [DeclareLaunchArgument(name, default_value=default, description=desc) for name, default, desc in ARGUMENTS]
        + [OpaqueFunction(function=_nodes)])
