"""System identification: the plant's parameters fitted to recorded depth under the recorded actuator commands.

Reads recordings with the mcap library itself (never through groundstation). Imports plant.
"""
