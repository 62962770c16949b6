def _lzf_decompress_into(data: bytes, out: npt.NDArray[np.uint8], start: int = 0, stop: int | None = None) -> int:
    """Decode the LZF stream ``data[start:stop]`` into ``out`` (uint8, C-contiguous); returns the bytes written."""


def _lzf_max_decompressed_len(n: int) -> int:
    """The most bytes an LZF stream of ``n`` bytes can decode to."""
