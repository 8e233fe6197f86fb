"""The bottom package: units, frames, quaternions and the truth record every layer may import.

It imports nothing from the project, so board/, peripherals/, firmware/, ioproc/, companion/
and hil/ can all depend on it without a cycle, and a constant such as standard gravity or a
quaternion product is written once.
"""
