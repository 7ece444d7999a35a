"""What people look at: the Rerun live view and replay, heatmaps, the dump plot.

May import recording, session, links and mcap_io; never cli or run.
"""
