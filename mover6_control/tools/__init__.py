"""Tools for people: the goal command line, the demo, plots. The top layer: it may use anything."""
