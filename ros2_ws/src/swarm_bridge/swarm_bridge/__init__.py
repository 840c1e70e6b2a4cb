"""XBee bridge to PIC16F690 omni-wheel robots, and a board emulator.

Bridge between the swarm agents and PIC16F690 omni-wheel robots over XBee API frames,
plus a board emulator.
"""
