"""Food delivery: orders, the run's order inbox, and the robot monitors the delivery mission uses."""
