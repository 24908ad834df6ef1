"""glTF 2.0 binary data: buffers, buffer views and accessors → NumPy arrays.

pygltflib parses the JSON and the GLB container; this module turns accessors into
arrays the way the glTF 2.0 specification (§3.6 Binary data storage) says:

- element layout from ``type`` (SCALAR … MAT4) and ``componentType`` (int8 … float32),
  little-endian;
- interleaved buffer views (``byteStride`` larger than the element) read through
  strides, without copying the buffer;
- ``normalized`` integer components mapped to [0, 1] (unsigned) or [-1, 1] (signed:
  ``max(c / (2^(n-1) - 1), -1)``, §3.11);
- an accessor without ``bufferView`` is zeros; ``sparse`` substitutes the listed
  elements;
- every range is checked against the buffer, so a truncated file is an error naming
  the accessor, not garbage.
"""

from __future__ import annotations

import base64
from pathlib import Path

import numpy as np

from snapcore.errors import GLTFError

__all__ = ["Buffers", "COMPONENT_DTYPES", "TYPE_SIZES"]

#: glTF componentType → little-endian NumPy dtype.
COMPONENT_DTYPES: dict[int, np.dtype] = {
    5120: np.dtype("<i1"),
    5121: np.dtype("<u1"),
    5122: np.dtype("<i2"),
    5123: np.dtype("<u2"),
    5125: np.dtype("<u4"),
    5126: np.dtype("<f4"),
}
#: glTF accessor type → number of components.
TYPE_SIZES = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9, "MAT4": 16}


#: Relative margin around an accessor's declared min/max before its data counts as damaged.
BOUNDS_MARGIN = 1e-3


def _normalise(a: np.ndarray) -> np.ndarray:
    """Normalised integers → float64 (glTF §3.11: signed clamp at -1)."""
    info = np.iinfo(a.dtype)
    if info.min < 0:
        return np.maximum(a.astype(np.float64) / info.max, -1.0)
    return a.astype(np.float64) / info.max


class Buffers:
    """The binary buffers of one glTF document, and accessor reads from them.

    Parameters
    ----------
    gltf : pygltflib.GLTF2
        The parsed document.
    path : Path
        Its file: external ``.bin`` files are resolved beside it; messages name it.
    """

    def __init__(self, gltf, path: Path):
        self.gltf = gltf
        self.path = Path(path)
        self._buffers: dict[int, bytes] = {}
        self._cache: dict[int, np.ndarray] = {}

    def error(self, message: str) -> GLTFError:
        return GLTFError(message, path=str(self.path))

    def buffer(self, i: int) -> bytes:
        """Bytes of buffer ``i`` (the GLB chunk, a data URI or a file beside the document)."""
        if i in self._buffers:
            return self._buffers[i]
        bufs = self.gltf.buffers or []
        if not 0 <= i < len(bufs):
            raise self.error(f"buffer {i} does not exist ({len(bufs)} buffers)")
        b = bufs[i]
        uri = b.uri
        if uri is None:
            data = self.gltf.binary_blob() if i == 0 else None
            if data is None:
                raise self.error(f"buffer {i} has no data (no uri and no GLB binary chunk)")
        elif uri.startswith("data:"):
            try:
                data = base64.b64decode(uri.split(",", 1)[1], validate=False)
            except (ValueError, IndexError) as err:
                raise self.error(f"buffer {i}: bad data URI ({err})") from err
        else:
            f = self.path.parent / uri
            if not f.is_file():
                raise self.error(f"buffer {i}: file '{uri}' not found beside the document")
            data = f.read_bytes()
        if b.byteLength is not None and len(data) < b.byteLength:
            raise self.error(f"buffer {i} is truncated: {len(data)} of {b.byteLength} bytes")
        self._buffers[i] = data
        return data

    def _view(
        self, v: int, offset: int, count: int, size: int, dtype: np.dtype, what: str
    ) -> np.ndarray:
        """(count, size) elements from buffer view ``v`` at ``offset``, honouring byteStride."""
        views = self.gltf.bufferViews or []
        if not 0 <= v < len(views):
            raise self.error(f"{what}: buffer view {v} does not exist")
        bv = views[v]
        data = self.buffer(bv.buffer)
        elem = size * dtype.itemsize
        stride = bv.byteStride or elem
        if stride < elem:
            raise self.error(f"{what}: byteStride {stride} is smaller than the {elem}-byte element")
        start = (bv.byteOffset or 0) + offset
        need = stride * (count - 1) + elem if count else 0
        if offset + need > bv.byteLength or start + need > len(data):
            raise self.error(
                f"{what} reaches past the end of its data (buffer view {v}, "
                f"{need} bytes from offset {start}; the file may be truncated)"
            )
        if count == 0:
            return np.zeros((0, size), dtype)
        arr = np.ndarray(
            (count, size), dtype=dtype, buffer=data, offset=start, strides=(stride, dtype.itemsize)
        )
        return arr.copy()

    def accessor(self, i: int) -> np.ndarray:
        """Accessor ``i`` as float64 or integer array of shape (count,) or (count, n).

        Matrices come back as (count, 4, 4) / (count, 3, 3) / (count, 2, 2) in row-major
        NumPy order (glTF stores them column-major). Normalised integers become float64.
        """
        if i in self._cache:
            return self._cache[i]
        accs = self.gltf.accessors or []
        if not 0 <= i < len(accs):
            raise self.error(f"accessor {i} does not exist ({len(accs)} accessors)")
        a = accs[i]
        what = f"accessor {i}"
        dtype = COMPONENT_DTYPES.get(a.componentType)
        if dtype is None:
            raise self.error(f"{what}: unknown componentType {a.componentType}")
        size = TYPE_SIZES.get(a.type)
        if size is None:
            raise self.error(f"{what}: unknown type {a.type!r}")
        if a.type in ("MAT2", "MAT3") and dtype.itemsize < 4:
            # columns would be padded to 4-byte boundaries (§3.6.2.4); no tool we read emits it
            raise self.error(
                f"{what}: {a.type} of {dtype.itemsize}-byte components is not supported"
            )
        count = int(a.count)
        if a.bufferView is None:
            out = np.zeros((count, size), dtype)
        else:
            out = self._view(a.bufferView, a.byteOffset or 0, count, size, dtype, what)
        if a.sparse is not None and a.sparse.count:
            sp = a.sparse
            idt = COMPONENT_DTYPES.get(sp.indices.componentType)
            if idt is None or idt.kind != "u":
                raise self.error(f"{what}: sparse indices need an unsigned componentType")
            idx = self._view(
                sp.indices.bufferView,
                sp.indices.byteOffset or 0,
                sp.count,
                1,
                idt,
                f"{what} sparse indices",
            )[:, 0].astype(np.int64)
            if idx.size and (idx.max() >= count):
                raise self.error(
                    f"{what}: sparse index {int(idx.max())} is past its {count} elements"
                )
            vals = self._view(
                sp.values.bufferView,
                sp.values.byteOffset or 0,
                sp.count,
                size,
                dtype,
                f"{what} sparse values",
            )
            out = out.copy()
            out[idx] = vals
        if a.normalized and dtype.kind in "iu":
            out = _normalise(out)
        elif dtype.kind == "f":
            # garbage bytes can be signalling NaNs, whose cast warns: non-finite data is
            # refused with one error line by floats(), not announced by numpy first
            with np.errstate(invalid="ignore"):
                out = out.astype(np.float64)
        if a.type.startswith("MAT"):
            n = int(round(size**0.5))
            out = out.reshape(count, n, n).transpose(0, 2, 1)  # column-major → row-major
        elif size == 1:
            out = out[:, 0]
        self._cache[i] = out
        return out

    def floats(self, i: int, what: str) -> np.ndarray:
        """Accessor ``i`` as float64, refusing non-finite values (a corrupt file)."""
        out = np.asarray(self.accessor(i), dtype=np.float64)
        if not np.all(np.isfinite(out)):
            raise self.error(f"{what} (accessor {i}) holds non-finite numbers")
        a = self.gltf.accessors[i]
        # Exporters must write the bounds of positions and key times (glTF 2.0 §5.1.1):
        # data far outside them is damaged (garbage bytes in the binary chunk). The
        # margin allows float32 rounding and loosely rounded bounds.
        if a.min is not None and a.max is not None and a.componentType == 5126 and out.size:
            lo, hi = np.asarray(a.min, float), np.asarray(a.max, float)
            # bounds are per stored component: matrices column-major, as in the file
            flat = (out.transpose(0, 2, 1) if out.ndim == 3 else out).reshape(out.shape[0], -1)
            if lo.size == hi.size == flat.shape[1]:
                tol = BOUNDS_MARGIN * (np.abs(hi - lo) + np.abs(hi) + np.abs(lo)) + 1e-6
                bad = np.any((flat < lo - tol) | (flat > hi + tol), axis=1)
                if np.any(bad):
                    k = int(np.argmax(bad))
                    raise self.error(
                        f"{what} (accessor {i}): element {k} is {flat[k].tolist()}, "
                        f"outside the declared min {lo.tolist()} / max "
                        f"{hi.tolist()}: the binary data is damaged"
                    )
        return out
