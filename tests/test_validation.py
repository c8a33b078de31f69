"""The shared checks: one error type and message form per mistake."""

from __future__ import annotations

import math

import numpy as np
import pytest

from qdcnn._fileio import atomic_write_bytes
from qdcnn._validation import (
    check_bool,
    check_choice,
    check_float,
    check_input_shape,
    check_int,
    check_odd,
    check_optional_shots,
    check_probability,
    check_seed,
    check_shape,
    has_shape,
    shape_text,
)
from qdcnn.errors import InputError, ParameterError


@pytest.mark.parametrize("bad", [True, 1.0, "3", None, 1, 101])
def test_check_int_refuses_non_integers_and_out_of_range(bad):
    with pytest.raises(ParameterError, match=r"n=.* is invalid: an integer in \[2, 100\]"):
        check_int("n", bad, 2, 100)


def test_check_int_accepts_numpy_integers():
    assert check_int("n", np.int64(7), 0) == 7 and type(check_int("n", np.int64(7), 0)) is int


@pytest.mark.parametrize("bad", [math.nan, math.inf, False, "0.5", 0.0])
def test_check_float_open_interval(bad):
    with pytest.raises(ParameterError, match=r"a finite number in \(0, 1\]"):
        check_float("x", bad, 0.0, 1.0, open_lo=True)


def test_other_checks():
    assert check_probability("p", 1) == 1.0
    with pytest.raises(ParameterError, match="a probability"):
        check_probability("p", 1.5)
    with pytest.raises(ParameterError, match="True or False"):
        check_bool("flag", 1)
    assert check_seed("seed", 2**32 - 1) == 2**32 - 1
    with pytest.raises(ParameterError):
        check_seed("seed", -1)
    with pytest.raises(ParameterError, match="one of 'a', 'b'"):
        check_choice("c", "z", ("a", "b"))
    with pytest.raises(ParameterError, match="odd"):
        check_odd("k", 4)
    assert check_optional_shots(None) is None
    with pytest.raises(ParameterError, match=r"shots=1e\+21"):
        check_optional_shots(1e21)


def test_atomic_write_refuses_a_symlink_and_leaves_its_target(tmp_path):
    victim = tmp_path / "victim.txt"
    victim.write_text("keep")
    link = tmp_path / "out.txt"
    link.symlink_to(victim)
    with pytest.raises(InputError) as info:
        atomic_write_bytes(link, b"new")
    assert str(info.value) == f"{link}: is a symbolic link; qdcnn never writes through one"
    assert victim.read_text() == "keep"
    assert link.is_symlink() and sorted(p.name for p in tmp_path.iterdir()) == [
        "out.txt",
        "victim.txt",
    ]


def test_atomic_write_into_a_directory_is_an_input_error(tmp_path):
    with pytest.raises(InputError, match="is a directory"):
        atomic_write_bytes(tmp_path, b"x")


@pytest.mark.parametrize(
    ("shape", "dims", "ok"),
    [
        ((2, 4, 4, 3), "N,H,W,3", True),
        ((2, 4, 4, 1), "N,H,W,3", False),
        ((4, 4), "H,W,3|H,W", True),
        ((4, 4, 2), "H,W,3|H,W", False),
        ((3,), "*,3", True),
        ((5, 2, 3), "*,3", True),
        ((), "*,3", False),
        ((6, 2), "6,F,*", True),
        ((6, 2, 9), "6,F,*", True),
        ((6,), "6,F,*", False),
        ((5, 1, 1), "5,*,1", True),
        ((), "", True),
    ],
)
def test_has_shape_reads_the_declared_axes(shape, dims, ok):
    assert has_shape(np.zeros(shape), dims) is ok


def test_shape_checks_name_the_shape_given():
    assert shape_text("B,4|4") == "(B, 4) or (4,)"
    check_shape("x", [[1.0, 2.0]], "B,2")
    with pytest.raises(ParameterError, match=r"^x='shape \(2, 3\)' is invalid: shape \(B, 2\)$"):
        check_shape("x", np.zeros((2, 3)), "B,2")
    with pytest.raises(ParameterError, match=r"^w='shape \(\)' is invalid: three angles$"):
        check_shape("w", 1.0, "*,3", "three angles")
    with pytest.raises(InputError, match=r"^img: expected shape \(H, W\), got shape \(1, 2, 3\)$"):
        check_input_shape("img", np.zeros((1, 2, 3)), "H,W")


def test_has_shape_reads_lists_and_tensors_like_arrays():
    assert has_shape([[1, 2, 3]], "B,3") and not has_shape([[1, 2]], "B,3")
    assert has_shape(np.float64(1.0), "") and has_shape([[[0, 0, 0]]], "H,W,3|H,W")


def test_atomic_write_npy_reads_back_memory_mapped_and_refuses_objects(tmp_path):
    from qdcnn._fileio import atomic_write_npy

    data = np.arange(2 * 3 * 4, dtype=np.uint8).reshape(2, 3, 4)
    path = atomic_write_npy(tmp_path / "sub" / "a.npy", data)
    back = np.load(path, mmap_mode="r", allow_pickle=False)
    assert isinstance(back, np.memmap) and back.dtype == np.uint8
    np.testing.assert_array_equal(back, data)
    assert sorted(p.name for p in path.parent.iterdir()) == ["a.npy"]  # no temporary left
    with pytest.raises(TypeError, match="no Python objects"):
        atomic_write_npy(tmp_path / "b.npy", np.array([{}], dtype=object))
    assert not (tmp_path / "b.npy").exists()
