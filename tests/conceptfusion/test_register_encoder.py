"""``register_encoder``: a user's encoder joins the one table every lookup reads, bad names and
factories are refused when registered, and a wrong answer (shape, NaN, inf, norm, type) is refused
at the call that returned it, naming the encoder, what was expected and what arrived."""

import numpy as np
import pytest

from conceptfusion import make_encoder, register_encoder
from conceptfusion.errors import EncoderOutputError
from conceptfusion.perception import registry
from conceptfusion.perception.checked import CheckedEncoder, CheckedTextEncoder
from conceptfusion.perception.featurizer import PerceptionSpec, load_encoder, make_featurizer, perception_names

DIM = 8


class Fixed:
    """Answers every text and image with fixed rows: ``text_rows(n)`` / ``image_rows(n)``."""

    dim = DIM

    def __init__(self, text_rows=None, image_rows=None, arg=None):
        self.arg = arg
        self._text = text_rows or (lambda n: np.eye(DIM, dtype=np.float32)[np.arange(n) % DIM])
        self._image = image_rows or self._text

    def encode_text(self, texts):
        return self._text(len(texts))

    def encode_image(self, images):
        return self._image(len(images))


class TextOnly:
    dim = DIM

    def encode_text(self, texts):
        return np.eye(DIM, dtype=np.float32)[: len(texts)]


@pytest.fixture(autouse=True)
def restore_registry():
    """Each test registers into the real table; it is put back afterwards."""
    saved, checks = dict(registry.ENCODERS), dict(registry._AVAILABLE)
    yield
    registry.ENCODERS.clear()
    registry.ENCODERS.update(saved)
    registry._AVAILABLE.clear()
    registry._AVAILABLE.update(checks)


def test_a_registered_encoder_is_known_to_every_lookup():
    register_encoder("fixed-unit", lambda arg: Fixed(arg=arg), description="fixed rows for tests")
    assert registry.parse_encoder_spec("Fixed-Unit:abc") == ("fixed-unit", "abc")
    assert "fixed-unit" in perception_names() and PerceptionSpec.parse("fixed-unit").encoder_name == "fixed-unit"
    assert registry.describe_encoders()["fixed-unit"] == "fixed rows for tests"
    enc = make_encoder("fixed-unit:ckpt-7")
    assert isinstance(enc, CheckedEncoder) and enc.wrapped.arg == "ckpt-7" and enc.dim == DIM
    out = enc.encode_text(["a", "b", "c"])
    assert out.dtype == np.float32 and out.shape == (3, DIM)
    np.testing.assert_allclose(out, np.eye(DIM)[:3])
    assert make_encoder("fixed-unit").wrapped.arg is None


def test_the_description_defaults_to_the_factory_docstring_then_its_name():
    def build(arg):
        """Builds the fixed encoder.

        More lines that the listing leaves out."""
        return Fixed()

    register_encoder("with-doc", build)
    register_encoder("no-doc", lambda arg: Fixed())
    lines = registry.describe_encoders()
    assert lines["with-doc"] == "Builds the fixed encoder."
    assert lines["no-doc"].startswith("user encoder (") and "<lambda>" in lines["no-doc"]


@pytest.mark.parametrize("name, error, match", [
    ("My Encoder", ValueError, r"expected lower case letters, digits, '-', '_' or '\.' .* got 'My Encoder'"),
    ("Mine", ValueError, r"got 'Mine'; 'mine' would do"),
    ("mine:v2", ValueError, r"':' separates a spec's name from its argument \(the factory receives 'v2' as it\)"),
    ("", ValueError, r"expected lower case letters.* got ''"),
    ("-mine", ValueError, r"starting with a letter or digit\), got '-mine'"),
    ("oracle", ValueError, r"'oracle' is reserved for privileged ground-truth perception"),
    ("oracle-open", ValueError, r"'oracle-open' is reserved"),
    ("color", ValueError, r"encoder 'color' is already registered; choose another name or pass replace=True"),
    (3, TypeError, r"name: expected a string such as 'my-clip', got int 3"),
])
def test_bad_names_are_refused(name, error, match):
    with pytest.raises(error, match=match):
        register_encoder(name, lambda arg: Fixed())


def test_bad_factories_are_refused_when_registered():
    with pytest.raises(TypeError, match=r"factory: expected a callable taking the spec's argument .* got Fixed"):
        register_encoder("inst", Fixed())
    with pytest.raises(TypeError, match=r"expected a callable taking one argument .* got TextOnly\(\); wrap it: lambda arg: TextOnly\(\)"):
        register_encoder("no-arg", TextOnly)
    with pytest.raises(TypeError, match="description: expected a string, got int"):
        register_encoder("desc", lambda arg: Fixed(), description=3)
    assert not {"inst", "no-arg", "desc"} & set(registry.ENCODERS)


def test_what_the_factory_builds_is_checked_when_built():
    register_encoder("no-text", lambda arg: object())
    with pytest.raises(TypeError, match=r"encoder 'no-text': the factory built object, expected an object with encode_text.*missing encode_text"):
        make_encoder("no-text")
    register_encoder("no-dim", lambda arg: type("NoDim", (), {"encode_text": lambda self, t: None, "dim": 0})())
    with pytest.raises(TypeError, match=r"encoder 'no-dim': the factory built NoDim whose dim is 0, expected an int >= 1"):
        make_encoder("no-dim")


def test_replace_swaps_the_encoder_even_where_it_was_loaded_before():
    register_encoder("swap", lambda arg: Fixed())
    first = load_encoder("swap")
    assert load_encoder("swap") is first
    register_encoder("swap", lambda arg: TextOnly(), replace=True)
    second = load_encoder("swap")
    assert isinstance(second.wrapped, TextOnly)
    register_encoder("onnx", lambda arg: Fixed(arg=arg), replace=True)
    registry.check_encoder_files("onnx:/no/such/folder")  # the built-in's folder check went with it
    assert make_encoder("onnx:/no/such/folder").wrapped.arg == "/no/such/folder"


def test_a_text_only_encoder_stays_text_only():
    register_encoder("text-only", lambda arg: TextOnly())
    enc = make_encoder("text-only")
    assert isinstance(enc, CheckedTextEncoder) and not hasattr(enc, "encode_image")
    assert enc.encode_text(["x"]).shape == (1, DIM)


def test_attributes_of_the_wrapped_encoder_reach_the_featurizer():
    class Calibrated(Fixed):
        info = {"metrics": {"score_floor": 0.42}}

    register_encoder("calibrated", lambda arg: Calibrated())
    assert make_featurizer("calibrated").score_floor == 0.42


def _rows(values):
    return lambda n: np.asarray(values, np.float32)


def _unit_but(row, scale):
    def rows(n):
        x = np.eye(DIM, dtype=np.float32)[:n].copy()
        x[row] *= scale
        return x
    return rows


def _nan_at(row, value):
    def rows(n):
        x = np.eye(DIM, dtype=np.float32)[:n].copy()
        x[row, 3] = value
        return x
    return rows


@pytest.mark.parametrize("rows, match", [
    (_rows(np.zeros((3, 5))), r"encoder 'bad': encode_text returned shape \(3, 5\), expected \(2, 8\) \(one row per text, dim 8\)"),
    (lambda n: np.eye(DIM, dtype=np.float32)[0], r"encode_text returned shape \(8,\), expected \(2, 8\)"),
    (_unit_but(1, 3.2), r"encoder 'bad': encode_text row 1 has norm 3\.2, expected unit vectors \(\|norm - 1\| <= 0\.001"),
    (_unit_but(0, 0.0), r"encode_text row 0 has norm 0, expected unit vectors"),
    (_nan_at(1, np.nan), r"encoder 'bad': encode_text returned NaN in row 1 \(1 of 2 rows not finite\), expected finite values"),
    (_nan_at(0, np.inf), r"encode_text returned inf in row 0"),
    (lambda n: np.eye(DIM)[:n].tolist(), r"encode_text returned list, expected a numpy array of shape \(2, 8\)"),
    (lambda n: np.eye(DIM, dtype=np.int64)[:n], r"encode_text returned dtype int64, expected floating point"),
])
def test_a_wrong_text_answer_is_refused_at_the_first_call(rows, match):
    register_encoder("bad", lambda arg: Fixed(text_rows=rows))
    enc = make_encoder("bad")
    with pytest.raises(EncoderOutputError, match=match):
        enc.encode_text(["red mug", "blue bowl"])


def test_a_wrong_image_answer_is_refused_naming_the_images():
    register_encoder("bad-image", lambda arg: Fixed(image_rows=_rows(np.eye(4, DIM))))
    enc = make_encoder("bad-image")
    assert enc.encode_text(["fine"]).shape == (1, DIM)
    images = [np.zeros((4, 5, 3), np.uint8)] * 2
    with pytest.raises(EncoderOutputError, match=r"encoder 'bad-image': encode_image returned shape \(4, 8\), expected \(2, 8\) \(one row per image, dim 8\)"):
        enc.encode_image(images)


def test_float64_unit_rows_pass_as_float32_and_inputs_are_checked_first():
    register_encoder("f64", lambda arg: Fixed(text_rows=lambda n: np.eye(DIM)[:n]))
    enc = make_encoder("f64")
    out = enc.encode_text(["a"])
    assert out.dtype == np.float32
    with pytest.raises(TypeError, match="expected a sequence of strings, got a single str"):
        enc.encode_text("a")
    with pytest.raises(TypeError, match=r"images\[0\]: expected uint8 RGB, got float64"):
        enc.encode_image([np.zeros((2, 2, 3))])
