"""The batch study: seeded trials of a learner on a preset, statistics, comparisons, sweeps and figures.

May import plant; never agent, serve or gym.
"""
