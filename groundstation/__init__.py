"""The host application: links, session, recorder, live view, replay and the `dive` CLI."""
