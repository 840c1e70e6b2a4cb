"""Fuzzing of the parsers that take bytes from outside (hypothesis).

Every parser must either return a valid value or raise its own ValueError subclass
with a message; any other exception is a crash. Crashes found are kept as explicit
regression examples with ``@example``.
"""

from __future__ import annotations

import json

from hypothesis import example, given, HealthCheck, settings
from hypothesis import strategies as st

from swarm_agent.mesh_messages import CostRow, MeshMessageError, NeighbourInfo
from swarm_common.shapes import load_shape, ShapeError

FUZZ = settings(max_examples=150, deadline=None,
                suppress_health_check=[HealthCheck.function_scoped_fixture])


@FUZZ
@given(st.binary(max_size=120))
@example(b'\x01' + bytes(19))
@example(b'\x02\x00\x00\x01' + bytes(10))
def test_mesh_message_decoders_never_crash(data):
    for decoder in (NeighbourInfo.decode, CostRow.decode):
        try:
            decoder(data)
        except MeshMessageError as exc:
            assert str(exc)


finite = st.floats(min_value=-1e3, max_value=1e3, allow_nan=False)
anything = st.one_of(st.none(), st.booleans(), st.integers(), finite,
                     st.floats(allow_nan=True), st.text(max_size=5))
point = st.one_of(st.lists(finite, min_size=2, max_size=2), st.lists(anything, max_size=3),
                  anything)
ring = st.one_of(st.lists(point, max_size=8), anything)
document = st.one_of(
    st.fixed_dictionaries({'outer': ring}, optional={'holes': st.lists(ring, max_size=2),
                                                     'obstacles': st.lists(ring, max_size=2)}),
    st.dictionaries(st.text(max_size=6), anything, max_size=3), anything)


@FUZZ
@given(document)
@example({'outer': [[0, 0], [1, 1], [1, 0], [0, 1]]})           # bow tie
@example({'outer': [[0, 0], [1, 0], [1, 1]], 'holes': [[[5, 5], [6, 5], [6, 6]]]})
@example({'outer': [[0, 0], [float('nan'), 0], [1, 1]]})
def test_json_shape_loader_never_crashes(tmp_path, doc):
    path = tmp_path / 'shape.json'
    path.write_text(json.dumps(doc))
    try:
        shape = load_shape(str(path))
    except ShapeError as exc:
        assert str(exc)
    else:
        assert shape.region.is_valid and shape.area > 0


@FUZZ
@given(st.binary(max_size=300))
def test_svg_and_png_loaders_never_crash_on_garbage(tmp_path, data):
    for suffix in ('.svg', '.png'):
        path = tmp_path / f'garbage{suffix}'
        path.write_bytes(data)
        try:
            load_shape(str(path))
        except ShapeError as exc:
            assert str(exc)
