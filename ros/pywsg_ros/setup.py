"""ament_python package of the pywsg ROS 2 node: `colcon build` it in a workspace (docs/ros.md)."""

from glob import glob

from setuptools import setup

PACKAGE = "pywsg_ros"

setup(
    name=PACKAGE,
    version="0.3.0",
    packages=[PACKAGE],
    data_files=[
        ("share/ament_index/resource_index/packages", [f"resource/{PACKAGE}"]),
        (f"share/{PACKAGE}", ["package.xml"]),
        (f"share/{PACKAGE}/launch", glob("launch/*.launch.py")),
        (f"share/{PACKAGE}/config", glob("config/*.yaml")),
    ],
    # pywsg is installed with pip (it is not a rosdep key); setup.py does not pull it so that colcon
    # never replaces the pywsg the user chose
    install_requires=["setuptools"],
    zip_safe=True,
    maintainer="the pywsg contributors",
    maintainer_email="pywsg@users.noreply.invalid",
    description="ROS 2 node for WSG grippers on pywsg",
    license="MIT",
    entry_points={"console_scripts": ["wsg_node = pywsg_ros.wsg_node:main"]},
)
