"""The user study: stimuli, the Streamlit app, and the store of participants' answers."""

from .store import Store, StoreError, read_export, write_export

__all__ = ["Store", "StoreError", "read_export", "write_export"]
