"""A system of your own: a puck pushed along a line (the example of the user guide)."""
