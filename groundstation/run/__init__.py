"""The main job, `dive run`: the runner that ties a session to a recorder, its hub for other tools, markers.

May import session, recording, links and mcap_io; never cli or view.
"""
