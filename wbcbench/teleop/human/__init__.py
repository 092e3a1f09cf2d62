"""The operator's body and its retargeting to the robot: :class:`HumanModel` (example-robot-data's human, scaled
to the operator), :func:`umeyama` alignment, reach shells of the robot's effectors, :class:`Retargeter` (operator
segment poses -> hand and head references), and the synthetic operator recordings generated from the human model
(:func:`generate_recordings`; the shipped ones through :func:`list_recordings` / :func:`open_recording`)."""

from . import model as _model
from . import registry as _registry
from . import retargeting as _retargeting
from . import synthetic as _synthetic
from . import umeyama as _umeyama
from . import workspace as _workspace
from .model import *  # noqa: F403
from .registry import *  # noqa: F403
from .retargeting import *  # noqa: F403
from .synthetic import *  # noqa: F403
from .umeyama import *  # noqa: F403
from .workspace import *  # noqa: F403

__all__ = [*_model.__all__, *_umeyama.__all__, *_workspace.__all__, *_retargeting.__all__, *_synthetic.__all__,
           *_registry.__all__]
