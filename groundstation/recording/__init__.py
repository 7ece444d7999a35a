"""Recordings on disk: the recorder, reading them back as tables, exports, `dive log info`.

May import session and mcap_io; never cli, run or view.
"""
