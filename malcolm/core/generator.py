"""PointGeneratorMeta: the meta of a scan argument (configure's ``generator``)."""

from __future__ import annotations

from typing import Any

from .errors import BadValueError
from .metas import Meta


class PointGeneratorMeta(Meta):
    """A scan: a scanspec Spec or a CompoundGenerator dict as GDA sends it.

    The value is kept as plain data (a Spec is serialized); validating it
    computes its points (``malcolm.scan.scan_points``), so a scan that cannot
    be done is refused here. Text is refused too, never opened: an argument
    is data, never a path on the server.
    """

    typeid = "malcolm:core/PointGeneratorMeta:1.0"

    def as_data(self, value: Any) -> Any:
        """``value`` as plain data, its points not computed: a scanspec Spec
        is serialized; None is refused (BadValueError)."""
        if value is None:
            raise BadValueError("a generator is required")
        if hasattr(value, "serialize"):  # a scanspec Spec: keep it plain data
            value = value.serialize()
        return value

    def validate(self, value: Any) -> Any:
        # malcolm.scan (scanspec, numpy) is loaded only when a scan is checked
        from malcolm.scan import GeneratorError, ScanPoints, scan_points

        if isinstance(value, ScanPoints):
            return value
        value = self.as_data(value)
        try:
            scan_points(value)
        except GeneratorError as e:
            raise BadValueError(str(e)) from None
        return value


#: the name runnable controllers have always used
GeneratorMeta = PointGeneratorMeta
