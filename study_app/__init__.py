"""The user study: stimuli, the Streamlit app, and the store of participants' answers."""

from .export import StoreError, read_export, write_export
from .store import Store

__all__ = ["Store", "StoreError", "read_export", "write_export"]
