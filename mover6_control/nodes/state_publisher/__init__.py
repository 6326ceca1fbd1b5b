"""The state publisher node: /robot_description, /tf, /tf_static (no robot_state_publisher)."""
