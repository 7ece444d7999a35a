"""The virtual agent as a process: the server loop, its transports (TCP, pty), link faults, the C firmware
hosts, `python -m simulator serve`.

May import agent and plant; never study or gym.
"""
