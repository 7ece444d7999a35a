"""A session with one agent: HELLO, clock, commands, parameters, dumps, events, backfill, keys.

May import links; never cli, run, view or recording.
"""
