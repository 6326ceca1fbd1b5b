"""The controller node and its parts (one class a module)."""
