"""uorb_bridge: uORB topics over a serial link between the FMU and a companion computer.

Split by concept: :mod:`.protocol` (the frame format and the stream decoder), :mod:`.topics`
(the topic list as data and the topic ids derived from the .msg definitions), :mod:`.params`
(UORB_BRG_CFG, SER_TEL2_BAUD) and :mod:`.module` (the module: one poll over the port and the
subscriptions). Design: ../shared/design (issue 24, item 2); docs/architecture.md.
"""

from firmware.modules.uorb_bridge.module import UorbBridgeModule

__all__ = ["UorbBridgeModule"]
