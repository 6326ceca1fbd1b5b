"""The web console (viser): a node and the parts of its page; see ``node``."""
