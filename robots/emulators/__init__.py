"""The firmware side of each serial protocol on a pseudo-terminal, driving the simulated robot,
so drivers are tested byte for byte without hardware."""
