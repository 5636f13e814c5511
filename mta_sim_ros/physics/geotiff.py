"""A height grid from a GeoTIFF (a digital elevation model), read by rasterio (GDAL): its first
band's heights, the world (x, y) of its first node and its spacing, in the file's projected
coordinate system (metres). Checked, each fault one line: a file GDAL reads, a projected CRS in
metres (a geographic one, degrees, is refused: reproject it, e.g. ``gdalwarp -t_srs EPSG:326NN``),
north-up square pixels (no rotation), no nodata cells, at most terrain.MAX_NODES nodes. Pixels
are the grid's nodes at their centres; the rows are turned to run along +y as every grid here.

rasterio is the ``terrain`` extra of setup.py: without it a .tif is refused in one line."""
from __future__ import annotations

import math
import os

import numpy as np

from ..validate import fail, show
from .terrain import MAX_FILE_BYTES, MAX_HEIGHT, MAX_NODES


def read_geotiff(path: str | os.PathLike, where: str = "terrain", source: str = "") \
        -> tuple[np.ndarray, tuple[float, float], float]:
    """(heights rows along +y, origin (x, y) of heights[0, 0], spacing m) of a GeoTIFF."""
    try:
        import rasterio
        from rasterio.errors import RasterioError
    except ImportError:
        fail("file", show(str(path)), "a .npy or .csv grid (a GeoTIFF needs rasterio: pip install 'mta_sim_ros[terrain]' or rasterio)", where,
             source)
    if os.path.getsize(path) > MAX_FILE_BYTES:
        fail("file", show(str(path)), f"at most {MAX_FILE_BYTES} bytes", where, source)
    try:
        with rasterio.open(path) as ds:
            _check_layout(ds, path, where, source)
            band = ds.read(1, masked=True)
            transform, rows = ds.transform, ds.height
    except RasterioError as err:
        fail("file", show(str(path)), f"a GeoTIFF GDAL reads ({str(err).splitlines()[0]})", where, source)
    if np.ma.is_masked(band) and band.mask.any():
        row, col = np.argwhere(band.mask)[0]
        fail("heights", f"a nodata cell at row {row}, column {col} of {show(str(path))}",
             "a grid without nodata (fill it, e.g. gdal_fillnodata)", where, source)
    heights = np.asarray(band.filled(np.nan) if np.ma.isMaskedArray(band) else band, dtype=np.float64)
    bad = np.argwhere(~np.isfinite(heights))
    if bad.size:  # named here, in the file's rows (grid_from's rows run along +y)
        row, col = bad[0]
        fail("heights", f"{heights[row, col]} at row {row}, column {col} of {show(str(path))}", "finite numbers (m)",
             where, source)
    if heights.size and float(np.max(np.abs(heights))) > MAX_HEIGHT:
        row, col = np.unravel_index(int(np.argmax(np.abs(heights))), heights.shape)
        fail("heights", f"{heights[row, col]:g} at row {row}, column {col} of {show(str(path))}",
             f"heights within +-{MAX_HEIGHT:g} m", where, source)
    a, e = transform.a, transform.e
    if e < 0:  # north-up: row 0 is the north edge; the grid's rows run along +y
        heights = heights[::-1]
        origin = (transform.c + 0.5 * a, transform.f + e * (rows - 0.5))
    else:
        origin = (transform.c + 0.5 * a, transform.f + 0.5 * e)
    return np.ascontiguousarray(heights), origin, abs(a)


def _check_layout(ds, path, where: str, source: str) -> None:
    """A projected CRS in metres, an axis-aligned transform of square pixels, not too many nodes."""
    name = show(str(path))
    if ds.width * ds.height > MAX_NODES:
        fail("heights", f"{ds.height} x {ds.width} nodes in {name}", f"at most {MAX_NODES} nodes", where, source)
    crs = ds.crs
    if crs is None or not crs.is_projected:
        fail("file", f"{name} in {crs.to_string() if crs else 'no coordinate system'}",
             "a GeoTIFF in a projected coordinate system in metres (reproject it: gdalwarp -t_srs EPSG:...)",
             where, source)
    units = (crs.linear_units or "").lower()
    if units not in ("metre", "meter", "m"):
        fail("file", f"{name} in {units or 'unknown'} units", "a projected coordinate system in metres", where, source)
    t = ds.transform
    if t.b != 0.0 or t.d != 0.0:
        fail("file", f"{name} with a rotated transform", "north-up pixels (no rotation: gdalwarp it)", where, source)
    if not math.isclose(abs(t.a), abs(t.e), rel_tol=1e-9) or t.a <= 0:
        fail("file", f"{name} with pixels of {t.a:g} x {abs(t.e):g} m", "square pixels with x growing east "
             "(gdalwarp -tr to resample)", where, source)
