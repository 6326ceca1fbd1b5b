"""Timing in one home: time laws, trajectories of many points and jerk-limited, time-optimal."""
