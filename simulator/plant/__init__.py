"""The water and what measures it: the plant and its compiled kernel, the sensor, the observer, the recovery controller
and the episode kernel.

Imports no other simulator folder.
"""
