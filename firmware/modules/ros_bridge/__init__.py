"""ros_bridge: the companion's uORB topics to and from ROS over the board's "ros" port."""

from firmware.modules.ros_bridge.module import RosBridgeModule

__all__ = ["RosBridgeModule"]
