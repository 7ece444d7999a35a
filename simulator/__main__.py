"""Entry point of `python -m simulator`: the ground station starts the virtual agent this way."""

from simulator.cli import main

if __name__ == "__main__":
    main()
