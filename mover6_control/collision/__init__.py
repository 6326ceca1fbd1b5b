"""Collision geometry of the arm, its table and keep-out zones, and the swept-motion checker."""
