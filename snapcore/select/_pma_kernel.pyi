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
def count_near(index: np.ndarray, near_bin: np.ndarray) -> int: ...
def gather_near(
    index: np.ndarray,
    near_bin: np.ndarray,
    b: np.ndarray,
    bn: np.ndarray,
    bc: np.ndarray,
    bcn: np.ndarray,
) -> None: ...
