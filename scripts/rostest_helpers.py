"""What the Python rostests (test/*_test.py) share: a TestCase with wait_for(), the /rosout
collection and distinct, increasing stamps; Outputs, the clouds of some topics by stamp."""
import threading
import time
import unittest

import rospy
from rosgraph_msgs.msg import Log
from sensor_msgs.msg import PointCloud2


class RosTestCase(unittest.TestCase):
    """unittest.TestCase with the waiting, log collection and stamps of the rostests."""

    WAIT_S = 60.0  # generous: the test machine may be slow; never a timing assertion
    POLL_S = 0.1  # how often wait_for() asks again [s]
    STAMP_BASE_S = 1000  # next_stamp(): the n-th stamp is STAMP_BASE_S + n s + n * STAMP_STEP_NS
    STAMP_STEP_NS = 1000
    stamp_counter = 0

    def wait_for(self, predicate, what, timeout=None):
        """Polls predicate() until it is true; fails the test after `timeout` s (default WAIT_S)
        or at shutdown."""
        timeout = self.WAIT_S if timeout is None else timeout
        deadline = time.monotonic() + timeout
        while not predicate():
            if time.monotonic() > deadline or rospy.is_shutdown():
                self.fail("timed out after %.0f s: %s" % (timeout, what))
            time.sleep(self.POLL_S)

    @classmethod
    def collect_rosout(cls, topics=("/rosout",)):
        """Keeps every Log message of `topics` in cls.rosout (guarded by cls.rosout_lock)."""
        cls.rosout = []
        cls.rosout_lock = threading.Lock()
        cls.rosout_subs = [rospy.Subscriber(t, Log, cls._on_rosout, queue_size=1000)
                           for t in topics]

    @classmethod
    def _on_rosout(cls, msg):
        with cls.rosout_lock:
            cls.rosout.append(msg)

    def logged(self, level, text):
        """Whether a message of at least `level` containing `text` reached cls.rosout."""
        with self.rosout_lock:
            return any(m.level >= level and text in m.msg for m in self.rosout)

    @classmethod
    def next_stamp(cls):
        """Distinct, increasing stamps: outputs are matched to inputs by stamp."""
        cls.stamp_counter += 1
        return rospy.Time(cls.STAMP_BASE_S + cls.stamp_counter,
                          cls.STAMP_STEP_NS * cls.stamp_counter)


class Outputs(object):
    """Messages of some output topics, keyed by (topic, stamp in ns)."""

    def __init__(self, topics, queue_size=50):
        self.lock = threading.Lock()
        self.got = {}
        self.subs = [rospy.Subscriber(t, PointCloud2, self._cb, callback_args=t,
                                      queue_size=queue_size) for t in topics]

    def _cb(self, msg, topic):
        with self.lock:
            self.got[(topic, msg.header.stamp.to_nsec())] = msg

    def get(self, topic, stamp):
        with self.lock:
            return self.got.get((topic, stamp.to_nsec()))

    def count(self, topic):
        with self.lock:
            return sum(1 for t, _ in self.got if t == topic)

    def close(self):
        for s in self.subs:
            s.unregister()
