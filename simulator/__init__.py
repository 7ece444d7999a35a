"""The virtual diving agent: plant, sensor, observer, controllers, on-board program, server and study runner."""
