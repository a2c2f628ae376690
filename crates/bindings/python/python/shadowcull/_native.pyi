# The compiled extension's stub. Callers use it only through the typed
# Python layer (shadowcull/__init__.py), which gives every public name its
# types; here every attribute is Any.
from typing import Any

__version__: str

def __getattr__(name: str) -> Any: ...
