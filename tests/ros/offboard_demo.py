"""Fly to a point in offboard mode over ROS 1 (mavros-style setpoint, PX4-style commands).

What a ROS user writes: run by Debian's /usr/bin/python3 (rospy's own interpreter) with the
generated px4_msgs on its path, from tests/ros/test_ros_flight.py. Arguments: east north up (m,
ENU, from where the vehicle stands), tolerance (m), time limit (s of ROS time). It prints one
line ``RESULT {json}``: the times of offboard, armed and the point held 2 s, the pose in ROS's
ENU and PX4's NED, and how the attitude stamps compare with ``rospy.Time.now()``.
"""
import json
import math
import sys

import rospy
from geometry_msgs.msg import PoseStamped
from px4_msgs.msg import VehicleAttitude, VehicleCommand, VehicleLocalPosition, VehicleStatus

east, north, up, tol, limit_s = map(float, sys.argv[1:6])
rospy.init_node("offboard_demo")
state = {"skew": []}


def on_attitude(m):
    state["skew"].append(rospy.Time.now().to_sec() - m.timestamp * 1e-6)


rospy.Subscriber("/fmu/out/vehicle_attitude", VehicleAttitude, on_attitude)
rospy.Subscriber("/fmu/out/vehicle_status", VehicleStatus, lambda m: state.update(status=m))
rospy.Subscriber("/fmu/out/vehicle_local_position", VehicleLocalPosition,
                 lambda m: state.update(lpos=m))
rospy.Subscriber("/fmu/local_position/pose", PoseStamped, lambda m: state.update(pose=m))
setpoint = rospy.Publisher("/fmu/setpoint_position/local", PoseStamped, queue_size=10)
command = rospy.Publisher("/fmu/in/vehicle_command", VehicleCommand, queue_size=10)


def send(cmd, p1=0.0, p2=0.0):
    m = VehicleCommand(command=cmd, param1=p1, param2=p2, target_system=1, target_component=1,
                       source_system=255, source_component=1, from_external=True)
    m.timestamp = rospy.Time.now().to_nsec() // 1000
    command.publish(m)


rate = rospy.Rate(20)  # on /clock (use_sim_time)
while not rospy.is_shutdown():  # the estimator has a position (GPS)
    lp = state.get("lpos")
    if lp is not None and lp.xy_valid and lp.z_valid and "pose" in state:
        break
    rate.sleep()
start = state["pose"].pose.position
target = PoseStamped()
target.header.frame_id = "map"
target.pose.position.x, target.pose.position.y = start.x + east, start.y + north
target.pose.position.z = start.z + up
target.pose.orientation.w = target.pose.orientation.z = math.sqrt(0.5)  # nose north (ENU yaw 90)
t0 = rospy.Time.now().to_sec()
out = {"t_start": t0, "start": [start.x, start.y, start.z]}
n, held_since = 0, None
while not rospy.is_shutdown() and rospy.Time.now().to_sec() - t0 < limit_s:
    target.header.stamp = rospy.Time.now()
    setpoint.publish(target)
    n += 1
    st = state.get("status")
    if n > 10 and n % 10 == 0 and st is not None:  # twice a second until offboard and armed
        if st.nav_state != VehicleStatus.NAVIGATION_STATE_OFFBOARD:
            send(VehicleCommand.VEHICLE_CMD_DO_SET_MODE, 1.0, 6.0)  # custom main mode offboard
        elif st.arming_state != VehicleStatus.ARMING_STATE_ARMED:
            send(VehicleCommand.VEHICLE_CMD_COMPONENT_ARM_DISARM, 1.0)
    if st is not None and st.nav_state == VehicleStatus.NAVIGATION_STATE_OFFBOARD:
        out.setdefault("t_offboard", rospy.Time.now().to_sec())
    if st is not None and st.arming_state == VehicleStatus.ARMING_STATE_ARMED:
        out.setdefault("t_armed", rospy.Time.now().to_sec())
    p = state["pose"].pose.position
    err = (p.x - target.pose.position.x, p.y - target.pose.position.y,
           p.z - target.pose.position.z)
    if all(abs(e) < tol for e in err):
        held_since = held_since or rospy.Time.now().to_sec()
        if rospy.Time.now().to_sec() - held_since >= 2.0:
            out["t_reached"] = held_since
            break
    else:
        held_since = None
    rate.sleep()
p, lp, st = state["pose"].pose.position, state["lpos"], state["status"]
out.update(pose=[p.x, p.y, p.z], target=[target.pose.position.x, target.pose.position.y,
                                          target.pose.position.z],
           lpos_ned=[lp.x, lp.y, lp.z], nav_state=st.nav_state, arming_state=st.arming_state,
           skew_min=min(state["skew"]), skew_max=max(state["skew"]),
           skew_q=[sorted(state["skew"])[int(f * (len(state["skew"]) - 1))]
                   for f in (0.0, 0.01, 0.1, 0.5, 0.9, 0.99, 1.0)],
           attitudes=len(state["skew"]), t_end=rospy.Time.now().to_sec())
print("RESULT " + json.dumps(out), flush=True)
