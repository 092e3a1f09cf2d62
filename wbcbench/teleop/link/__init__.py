"""The operator's pose stream over the network: the datagram format (:mod:`.protocol`), the non-blocking
:class:`UdpPoseReceiver`, the loopback :class:`ReplaySender`, network impairment (latency, loss, reordering ...) on a
relay or in simulated time (:mod:`.network`), and :class:`PosePredictor` over the link's delay."""

from . import network as _network
from . import prediction as _prediction
from . import protocol as _protocol
from . import receiver as _receiver
from . import sender as _sender
from .network import *  # noqa: F403
from .prediction import *  # noqa: F403
from .protocol import *  # noqa: F403
from .receiver import *  # noqa: F403
from .sender import *  # noqa: F403

__all__ = [*_protocol.__all__, *_receiver.__all__, *_sender.__all__, *_network.__all__, *_prediction.__all__]
