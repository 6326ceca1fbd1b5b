"""
The driver node of the real Mover6 (``node.DriverNode``), built from small parts.

``node`` (the lifecycle node: parameters and transitions), ``arm_session`` (the arm
between configure and cleanup: requests, activation, recovery; no ROS), ``jog_intake``
(/JointJog checked, commanded or refused), ``report_publisher`` (/joint_states and
/diagnostics on a thread of its own) and ``trigger_services`` (the std_srvs/Trigger services
on a node and executor of their own). docs/driver.md tells the lifecycle and the services.
"""
