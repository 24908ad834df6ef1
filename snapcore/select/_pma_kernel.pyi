"""Types of the compiled kernels (snapcore/select/_pma_kernel.pyx: what each one does)."""

import numpy as np

def swept_block(
    x: np.ndarray,
    links: np.ndarray,
    floor: float,
    b: np.ndarray,
    bn: np.ndarray,
    quads: np.ndarray,
    off: int,
) -> None: ...
def bin_vectors(
    b: np.ndarray, res: int, chunk: int, index: np.ndarray, gen: np.ndarray
) -> None: ...
def near_members(index: np.ndarray, near_bin: np.ndarray, out: np.ndarray) -> int: ...
