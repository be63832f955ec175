"""Small scenes for the model tests, written as bench files (the model builds scenes from data only)."""

from __future__ import annotations

import pytest
from wearbench.bench.load import load_bench, parse_bench, shipped_bench

DISC = """
driver = []
[bench]
name = "disc"
[operating]
speed = "0 rad/s"
gravity = ["0 m/s^2", "{g} m/s^2"]
[materials.steel]
youngs_modulus = "206 GPa"
poisson_ratio = 0.3
hardness = "217 MPa"
[contact]
law = "{law}"
restitution = {ce}
friction_coefficient = {cf}
[frame]
points = {{ O = ["0 m", "0 m"] }}
[[body]]
name = "disc"
mass = "1 kg"
inertia = "1e-4 kg*m^2"
points = {{ c = ["0 m", "0 m"] }}
[[joint]]
name = "J"
type = "revolute"
bodies = ["frame", "disc"]
points = ["O", "c"]
[joint.clearance]
bearing_body = "frame"
bearing_radius = "15 mm"
journal_radius = "14.5 mm"
bearing_material = "steel"
journal_material = "steel"
axial_length = "20 mm"
"""

PENDULUM = """
driver = []
[bench]
name = "pendulum"
[operating]
speed = "0 rad/s"
gravity = ["0 m/s^2", "-9.81 m/s^2"]
[frame]
points = { O = ["0 m", "0 m"], T = ["1 m", "1 m"] }
[[body]]
name = "bar"
length = "1 m"
mass = "1 kg"
inertia = "0.0833333333333 kg*m^2"
[[joint]]
name = "O"
type = "revolute"
bodies = ["frame", "bar"]
points = ["O", "start"]
"""


def disc_bench(g: float = 0.0, law: str = "lankarani-nikravesh", ce: float = 1.0, cf: float = 0.0):
    return parse_bench(DISC.format(g=g, law=law, ce=ce, cf=cf))


@pytest.fixture
def pendulum_bench():
    return parse_bench(PENDULUM)


@pytest.fixture(scope="session")
def ninebar():
    return load_bench(shipped_bench("ninebar"))


@pytest.fixture(scope="session")
def slider_crank():
    return load_bench(shipped_bench("slider-crank"))
