"""
Pose-goal motion for the Mover6: ROS-free core plus thin ROS 2 nodes.

numpy's OpenBLAS computes on its caller's thread only (``OPENBLAS_NUM_THREADS=1`` unless set,
here, before numpy is loaded): its worker threads busy-wait after each call, and in a node at
real-time priority they would take a CPU (``mover6_control.realtime.blas_on_one_thread``).
"""

import os

os.environ.setdefault('OPENBLAS_NUM_THREADS', '1')
