#!/usr/bin/env python3
"""Publishes one static transform on /tf_static, like tf2_ros' static_transform_publisher, which
Debian's ROS packages do not ship (python3-tf2-ros has the broadcaster, not the tool).

Same arguments, same order as static_transform_publisher:
  rosrun ground_filter static_tf.py X Y Z YAW PITCH ROLL PARENT CHILD
  rosrun ground_filter static_tf.py X Y Z QX QY QZ QW PARENT CHILD
metres and radians; the transform takes points of CHILD into PARENT (CHILD's pose in PARENT).
In a launch file:
  <node pkg="ground_filter" type="static_tf.py" name="velodyne_tf"
        args="0 0 1.7 0 0.349 0 base_link velodyne"/>
It stays up (the message is latched: late subscribers get it too) until shut down.
"""
import math
import sys

USAGE = __doc__.split("\n\n")[1]


class BadArguments(ValueError):
    pass


def quaternion_from_ypr(yaw, pitch, roll):
    """(x, y, z, w) of the rotation yaw about z, then pitch about y, then roll about x (fixed
    axes: R = Rz(yaw) Ry(pitch) Rx(roll)), as static_transform_publisher reads them."""
    cy, sy = math.cos(yaw / 2), math.sin(yaw / 2)
    cp, sp = math.cos(pitch / 2), math.sin(pitch / 2)
    cr, sr = math.cos(roll / 2), math.sin(roll / 2)
    return (sr * cp * cy - cr * sp * sy,
            cr * sp * cy + sr * cp * sy,
            cr * cp * sy - sr * sp * cy,
            cr * cp * cy + sr * sp * sy)


def parse(argv):
    """(translation, quaternion, parent, child) from the 8 or 9 arguments; BadArguments says
    which one is wrong."""
    if len(argv) not in (8, 9):
        raise BadArguments("expected 8 arguments (X Y Z YAW PITCH ROLL PARENT CHILD) or 9 "
                           "(X Y Z QX QY QZ QW PARENT CHILD), got %d" % len(argv))
    names = ["X", "Y", "Z"] + (["YAW", "PITCH", "ROLL"] if len(argv) == 8 else
                               ["QX", "QY", "QZ", "QW"])
    numbers = []
    for name, text in zip(names, argv[:-2]):
        try:
            v = float(text)
        except ValueError:
            raise BadArguments("%s = '%s' is not a number" % (name, text))
        if not math.isfinite(v):
            raise BadArguments("%s = '%s' is not finite" % (name, text))
        numbers.append(v)
    parent, child = argv[-2].strip(), argv[-1].strip()
    if not parent or not child:
        raise BadArguments("PARENT and CHILD must be frame names, got '%s' and '%s'"
                           % (argv[-2], argv[-1]))
    if parent.lstrip("/") == child.lstrip("/"):
        raise BadArguments("PARENT and CHILD are the same frame '%s'" % parent)
    if len(argv) == 8:
        q = quaternion_from_ypr(*numbers[3:6])
    else:
        norm = math.sqrt(sum(c * c for c in numbers[3:7]))
        if norm < 1e-9:
            raise BadArguments("the quaternion QX QY QZ QW is zero")
        q = tuple(c / norm for c in numbers[3:7])
    return tuple(numbers[:3]), q, parent, child


def main():
    import rospy
    argv = rospy.myargv(sys.argv)[1:]  # without roslaunch's __name:= / __log:= arguments
    if argv in (["-h"], ["--help"]):
        print(USAGE)
        return 0
    try:
        translation, q, parent, child = parse(argv)
    except BadArguments as e:
        sys.stderr.write("static_tf.py: %s\n%s\n" % (e, USAGE))
        return 2
    import tf2_ros
    from geometry_msgs.msg import TransformStamped
    rospy.init_node("static_tf", anonymous=True)
    t = TransformStamped()
    t.header.stamp = rospy.Time.now()
    t.header.frame_id = parent
    t.child_frame_id = child
    t.transform.translation.x, t.transform.translation.y, t.transform.translation.z = translation
    (t.transform.rotation.x, t.transform.rotation.y, t.transform.rotation.z,
     t.transform.rotation.w) = q
    broadcaster = tf2_ros.StaticTransformBroadcaster()
    broadcaster.sendTransform(t)
    rospy.loginfo("static transform %s -> %s: translation %s, rotation (x y z w) %s", parent,
                  child, " ".join("%g" % v for v in translation),
                  " ".join("%.6f" % v for v in q))
    rospy.spin()
    return 0


if __name__ == "__main__":
    sys.exit(main())
