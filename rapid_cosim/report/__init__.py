"""Tables and figures, built from archives and trajectories only."""
