"""The pywsg ROS 2 node's ament package: ``wsg_node`` runs :func:`pywsg.ros.main`."""
