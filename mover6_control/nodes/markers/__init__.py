"""The markers node: the goal, the planned path, the table and the keep-out boxes on /markers."""
