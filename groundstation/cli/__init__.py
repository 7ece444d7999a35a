"""The `dive` command line: the typer app and every command's body.

May import everything in groundstation.
"""
