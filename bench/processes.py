"""A node of this source tree in its own process, for the benchmarks; stopped by its pid."""

import os
import signal
import subprocess


class NodeProcess:
    """Run ``cmd`` in ``cwd`` with its output in ``log_path``; ``stop`` ends it by its pid."""

    def __init__(self, cmd, log_path, cwd):
        self.log_path = log_path
        self.log = open(log_path, 'w')
        self.proc = subprocess.Popen(cmd, stdout=self.log, stderr=subprocess.STDOUT, cwd=cwd,
                                     env=dict(os.environ, PYTHONUNBUFFERED='1'))
        self.pid = self.proc.pid

    def tail(self, lines=30):
        """Return the last lines of the node's output."""
        with open(self.log_path) as f:
            return ''.join(f.readlines()[-lines:])

    def stop(self):
        """Stop the process by its pid: SIGINT, then SIGKILL after 10 s."""
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGINT)
            try:
                self.proc.wait(10.0)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait(5.0)
        self.log.close()
