"""The recorder node and its bag writer (rosbag2 MCAP through rosbags)."""
