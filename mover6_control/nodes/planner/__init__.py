"""The planner node and its parts (one class a module)."""
