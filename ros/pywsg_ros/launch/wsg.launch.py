"""Launch the WSG gripper node: ros2 launch pywsg_ros wsg.launch.py url:=tcp://192.168.1.20:1000

Arguments: url (the gripper), params_file (default: this package's config/wsg.yaml), name (node name),
namespace, autostart (true: the node configures and activates itself; false: a lifecycle manager does).
"""

from pathlib import Path

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import LifecycleNode
from launch_ros.parameter_descriptions import ParameterValue


def generate_launch_description() -> LaunchDescription:
    share = Path(get_package_share_directory("pywsg_ros"))
    args = [
        DeclareLaunchArgument("url", default_value="tcp://192.168.1.20:1000", description="gripper address"),
        DeclareLaunchArgument("params_file", default_value=str(share / "config" / "wsg.yaml")),
        DeclareLaunchArgument("name", default_value="wsg_gripper"),
        DeclareLaunchArgument("namespace", default_value=""),
        DeclareLaunchArgument("autostart", default_value="true"),
    ]
    node = LifecycleNode(
        package="pywsg_ros",
        executable="wsg_node",
        name=LaunchConfiguration("name"),
        namespace=LaunchConfiguration("namespace"),
        output="screen",
        parameters=[
            LaunchConfiguration("params_file"),
            {"url": LaunchConfiguration("url"),
             "autostart": ParameterValue(LaunchConfiguration("autostart"), value_type=bool)},
        ],
        # joint_states for robot_state_publisher: remap here if it listens elsewhere
        remappings=[("joint_states", "/joint_states")],
    )
    return LaunchDescription([*args, node])
