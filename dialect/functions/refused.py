"""Trino functions lakegate refuses by name (NOT_SUPPORTED, with the reason) rather than as unknown names
(FUNCTION_NOT_FOUND is for names Trino does not have).
"""

from __future__ import annotations

from lakegate.dialect import registry

# === rejected =====================================================================================
_GEO = (
    "ST_Area ST_AsBinary ST_AsText ST_Boundary ST_Buffer ST_Centroid ST_Contains ST_ConvexHull ST_CoordDim "
    "ST_Crosses ST_Difference ST_Dimension ST_Disjoint ST_Distance ST_EndPoint ST_Envelope ST_Equals "
    "ST_ExteriorRing ST_GeometryFromText ST_GeomFromBinary ST_Intersection ST_Intersects ST_IsClosed "
    "ST_IsEmpty ST_IsRing ST_IsSimple ST_IsValid ST_Length ST_LineFromText ST_LineString ST_MultiPoint "
    "ST_NumPoints ST_Overlaps ST_Point ST_PointN ST_Points ST_Polygon ST_Relate ST_StartPoint ST_Touches "
    "ST_Union ST_Within ST_X ST_Y ST_XMax ST_XMin ST_YMax ST_YMin bing_tile bing_tile_at bing_tile_quadkey "
    "great_circle_distance geometry_union spatial_partitioning to_spherical_geography to_geometry"
).split()


#: Why the distribution functions stay refused (trinodb/trino operator/scalar/MathFunctions.java): Trino
#: computes them with Apache Commons Math (Erf.erf / erfInv, BetaDistribution: series and continued
#: fractions over its own FastMath.exp and log). Its erf (Gamma.regularizedGammaP(0.5, x*x), to 1e-15)
#: and libm's erf give a different normal_cdf(0, 1, x) for about one x in five in [-8, 8], though they
#: agree on every value of Trino's TestMathFunctions; reproducing it bit for bit means porting FastMath.
_COMMONS_MATH = (
    "Trino computes it with Apache Commons Math, whose last bits DuckDB's and Python's math functions do not reproduce"
)


REJECTED: dict[str, str] = {
    **{name.lower(): "geospatial functions are not available in lakegate" for name in _GEO},
    "shuffle": "random permutation not translated",
    "approx_most_frequent": "Trino's stream-summary estimate of the top values and their counts is not reproduced",
    "numeric_histogram": "Trino's approximate streaming histogram (Ben-Haim and Tom-Tov) is not reproduced",
    "checksum": "Trino's xxhash64-based checksum cannot be reproduced",
    "approx_set": "HyperLogLog state functions are not available",
    "empty_approx_set": "HyperLogLog state functions are not available",
    "merge": "HyperLogLog / qdigest / tdigest state functions are not available",
    "cardinality_hll": "HyperLogLog state functions are not available",
    "qdigest_agg": "qdigest state functions are not available",
    "tdigest_agg": "tdigest state functions are not available",
    "value_at_quantile": "qdigest / tdigest state functions are not available",
    "values_at_quantiles": "qdigest / tdigest state functions are not available",
    "quantile_at_value": "qdigest / tdigest state functions are not available",
    "make_set_digest": "setdigest state functions are not available",
    "merge_set_digest": "setdigest state functions are not available",
    "intersection_cardinality": "setdigest state functions are not available",
    "jaccard_index": "setdigest state functions are not available",
    "hash_counts": "setdigest state functions are not available",
    "learn_classifier": "machine learning functions are not available",
    "learn_regressor": "machine learning functions are not available",
    "learn_libsvm_classifier": "machine learning functions are not available",
    "learn_libsvm_regressor": "machine learning functions are not available",
    "classify": "machine learning functions are not available",
    "regress": "machine learning functions are not available",
    "features": "machine learning functions are not available",
    "evaluate_classifier_predictions": "machine learning functions are not available",
    "word_stem": "language stemming not translated",
    "uuid": "random UUIDs not translated",
    "color": "color functions are not available",
    "bar": "color functions are not available",
    "render": "color functions are not available",
    "rgb": "color functions are not available",
    "beta_cdf": _COMMONS_MATH,
    "inverse_beta_cdf": _COMMONS_MATH,
    "normal_cdf": _COMMONS_MATH,
    "inverse_normal_cdf": _COMMONS_MATH,
    "version": "answered by the SQL endpoint, not the dialect layer",
    "ip_prefix": "IP address functions are not available",
}


NOT_TRANSLATED: dict[str, str] = {
    "title_case": "not translated (string.md)",
    "timezone": "not translated (datetime.md: the zone identifier of a timestamp or time with time zone)",
    "from_iso8601_timestamp_nanos": "DuckDB has no nanosecond timestamp with time zone",
}


def install() -> None:
    """Register the functions of this page (called by pages.py)."""

    registry.REJECTED.update(REJECTED)

    registry.REJECTED.update(NOT_TRANSLATED)
