"""Start-up code shared by the scripts and tests that run roscore/roslaunch themselves
(scripts/rviz_screenshot.py, test/test_install_space.py, test/bag_playback_test.py).

Containers often have a hostname that does not resolve; ROS then fails with `cannot resolve host
address`. loopback_env() keeps a working ROS_HOSTNAME/ROS_IP/ROS_MASTER_URI of the user and
otherwise points them at the loopback interface (scripts/common.sh does the same for the shell
scripts: gf_ros_env)."""
import os
import signal
import socket
import subprocess
import sys
import threading

LOOPBACK = "localhost"
DEFAULT_MASTER_PORT = 11311


def resolves(host):
    """True when `host` (a name or an address) resolves to an address."""
    try:
        return bool(socket.getaddrinfo(host, None))
    except (socket.gaierror, UnicodeError, ValueError):
        return False


def free_port():
    """A TCP port on the loopback interface that was free a moment ago."""
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()
    return port


def loopback_env(env=None, master_port=None, log=None):
    """A copy of `env` (default os.environ) in which ROS can start on this machine.

    ROS_HOSTNAME / ROS_IP: kept when set and resolvable, else ROS_HOSTNAME=localhost (and
    ROS_IP dropped). ROS_MASTER_URI: http://localhost:`master_port` when a port is given (a
    private master), else kept when set and its host resolves, else http://localhost:11311.
    `log` (a function of one string) hears about every value that was replaced."""
    env = dict(os.environ if env is None else env)
    say = log or (lambda msg: None)
    host, ip = env.get("ROS_HOSTNAME", ""), env.get("ROS_IP", "")
    if host and not resolves(host):
        say("ROS_HOSTNAME=%s does not resolve: using %s" % (host, LOOPBACK))
        host = ""
    if not host and ip and not resolves(ip):
        say("ROS_IP=%s is not an address: using ROS_HOSTNAME=%s" % (ip, LOOPBACK))
        ip = ""
    if host:
        env["ROS_HOSTNAME"] = host
    elif ip:
        env.pop("ROS_HOSTNAME", None)
    else:
        env.pop("ROS_IP", None)
        env["ROS_HOSTNAME"] = LOOPBACK
    if master_port is not None:
        env["ROS_MASTER_URI"] = "http://%s:%d" % (LOOPBACK, master_port)
    else:
        uri = env.get("ROS_MASTER_URI", "")
        uri_host = uri.split("://", 1)[-1].split("/", 1)[0].rsplit(":", 1)[0] if uri else ""
        if not uri_host or not resolves(uri_host):
            if uri:
                say("ROS_MASTER_URI=%s does not resolve: using %s" % (uri, LOOPBACK))
            env["ROS_MASTER_URI"] = "http://%s:%d" % (LOOPBACK, DEFAULT_MASTER_PORT)
    return env


class Process(object):
    """A child in its own session (so Ctrl-C reaches its whole tree) whose combined output is
    collected line by line in `lines` by a reader thread."""

    def __init__(self, cmd, env=None, text=True):
        self.proc = subprocess.Popen(cmd, env=env, stdout=subprocess.PIPE,
                                     stderr=subprocess.STDOUT, universal_newlines=text,
                                     start_new_session=True)
        self.lines = []
        self._reader = threading.Thread(target=lambda: self.lines.extend(self.proc.stdout),
                                        daemon=True)
        self._reader.start()

    @property
    def pid(self):
        return self.proc.pid

    def running(self):
        return self.proc.poll() is None

    def output(self):
        """Everything printed so far, as one string."""
        chunks = list(self.lines)
        if chunks and isinstance(chunks[0], bytes):
            return b"".join(chunks).decode("utf-8", "replace")
        return "".join(chunks)

    def stop(self, timeout=20.0):
        """SIGINT to the process group (roslaunch shuts its nodes down), SIGKILL after
        `timeout` seconds; waits for the exit and the reader. Returns the exit status."""
        if self.proc.poll() is None:
            try:
                os.killpg(self.proc.pid, signal.SIGINT)
                self.proc.wait(timeout=timeout)
            except subprocess.TimeoutExpired:
                os.killpg(self.proc.pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
        rc = self.proc.wait()
        self._reader.join(timeout=5)
        return rc


def roslaunch(args, port=None, env=None, text=True):
    """`roslaunch [-p PORT] ARGS...` with loopback_env(env, port): a Process."""
    cmd = ["roslaunch"] + (["-p", str(port)] if port is not None else []) + list(args)
    return Process(cmd, env=loopback_env(env, master_port=port,
                                         log=lambda m: print("[ros] " + m, file=sys.stderr)),
                   text=text)
