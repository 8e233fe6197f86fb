"""The FMU (Pixhawk 1's STM32F427, PX4 fmu-v2) as a board, assembled beside the firmware it boots.

As ``ioproc/`` holds the IO's board and ``companion/`` the companion computer's, this package
holds the FMU's: :mod:`fmu.board` (:class:`~fmu.board.FmuV2Board`: the spec's devices on their
buses and pins, the ports that leave the chip, the firmware's start-up), and the pieces it is
built from (:mod:`fmu.can`: CAN1/CAN2 and the DroneCAN nodes plugged in; :mod:`fmu.pwm`: the
AUX outputs; :mod:`fmu.can_port`: a host tool's node on a CAN bus). ``board/`` keeps what
every board shares: the kernel, the wires, the timers and the specs.
"""
