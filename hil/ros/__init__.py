"""The ROS 1 edge of fmu-hil (rospy, threads allowed here only): message types, node, links."""
