"""Message codecs: ROS messages to and from the core's values, and raw CDR readers."""
