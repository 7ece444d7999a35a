"""The on-board program as the virtual agent runs it: the program, its link, mission, log ring, parameters table and
the simulated hardware.

May import plant; never serve, study or gym.
"""
