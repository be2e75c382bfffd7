"""azee_mj: realize AZee sign-language scores as the motion of a MuJoCo signer.

Units in the API: metres, radians, seconds; quaternions are ``wxyz``.
"""

from azee_mj.errors import AzeeError
from azee_mj.model import MODEL_PATH, SCENE_PATH, load_model
from azee_mj.sites import DEFAULT_MAP, SignerMap

__version__ = "0.1.0"

__all__ = ["DEFAULT_MAP", "MODEL_PATH", "SCENE_PATH", "AzeeError", "SignerMap", "load_model"]
