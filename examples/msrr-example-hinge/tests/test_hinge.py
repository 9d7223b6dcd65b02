"""The hinge robot keeps the platform's contract."""

from msrr.core.app.testing import check_robot


def test_hinge_conforms() -> None:
    check_robot("hinge")
