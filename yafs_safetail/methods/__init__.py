"""Methods: what decides where a request's copies go.

:class:`Policy` is the protocol every method implements (SafeTail, the baselines, a user's own);
``registry`` holds the method names; ``safetail`` is the learner of §III. Importing this package
does not import TensorFlow.
"""

from yafs_safetail.methods.baselines import MinLoadX, MinPropX, Oracle, RandX
from yafs_safetail.methods.policy import Policy, PolicyError
from yafs_safetail.methods.registry import make_baseline

__all__ = ["MinLoadX", "MinPropX", "Oracle", "Policy", "PolicyError", "RandX", "make_baseline"]
