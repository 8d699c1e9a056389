"""Encoders by name: the one lookup table the command line and the harness use.

A spec is ``NAME`` or ``NAME:ARGUMENT``:

- ``color``: :class:`~conceptfusion.perception.encoders.ColorNameEncoder` (``Encoder``; tests, demo).
- ``minilm-text``: the offline MiniLM text tower (``TextEncoder``: text only).
- ``hf:HUB_ID`` or ``hf:/local/dir``: Hugging Face CLIP (``Encoder``; :mod:`conceptfusion.perception.clip_hf`).
- ``onnx:DIR``: CLIP exported to ONNX (``Encoder``; :mod:`conceptfusion.perception.clip_onnx`).
- ``embedded`` or ``embedded:DIR``: the embedded image tower + MiniLM text tower (``Encoder``);
  without an argument, the v1 weights shipped with the package (:data:`DEFAULT_ENCODER`), trained
  on the v1 world's 7 kinds x 10 colours.
- ``embedded-v2``: the same with the shipped v2 weights, trained on the object library's train
  split (the default perception of the v2 suites).
- ``audio-onnx:DIR``: an audio-language encoder in ONNX (``AudioEncoder``; :mod:`conceptfusion.perception.audio`).

Your own encoder joins the same table with :func:`register_encoder` (from a module that
``cfharness run --import`` imports, or from Python before making maps); its answers are checked
at every call (:mod:`conceptfusion.perception.checked`).

``embedded`` is registered only where :mod:`conceptfusion.perception.image_tower` exists. Oracle
features (:mod:`conceptfusion.perception.oracle`) read the simulator's segmentation and are not an
encoder, so they are not listed here. Factories import their heavy dependencies only when
called, so importing this module is cheap.
"""

from __future__ import annotations

import importlib.util
import inspect
import re
from pathlib import Path
from typing import Callable

from conceptfusion.names import unknown_name_error

__all__ = ["ENCODERS", "DEFAULT_ENCODER", "RESERVED_ENCODER_NAMES", "ENCODER_NAME_PATTERN", "register_encoder", "parse_encoder_spec",
           "make_encoder", "check_encoder_files", "describe_encoders"]

DEFAULT_ENCODER = "embedded"
"""The spec the harness uses when none is given: the shipped embedded tower (offline, CPU)."""


def _no_arg(name: str, arg: str | None) -> None:
    if arg is not None:
        raise ValueError(f"encoder {name!r} takes no argument, got {name}:{arg}")


def _need_arg(name: str, arg: str | None, what: str) -> str:
    if arg is None or not arg.strip():
        raise ValueError(f"encoder {name!r} needs {what}: expected {name}:{what.upper().replace(' ', '_')}")
    return arg.strip()


def _color(arg: str | None):
    """ColorNameEncoder: a tiny deterministic test encoder that knows only colours."""
    from conceptfusion.perception.encoders import ColorNameEncoder

    _no_arg("color", arg)
    return ColorNameEncoder()


def _minilm(arg: str | None):
    """all-MiniLM-L6-v2 text tower, offline, 384-d (text only)."""
    from conceptfusion.perception.text_tower import MiniLMTextEncoder

    _no_arg("minilm-text", arg)
    return MiniLMTextEncoder()


def _hf(arg: str | None):
    """Hugging Face CLIP: hf:HUB_ID or hf:/local/dir."""
    from conceptfusion.perception.clip_hf import HFClipEncoder

    return HFClipEncoder(_need_arg("hf", arg, "hub id or dir"))


def _onnx(arg: str | None):
    """CLIP exported to ONNX, run by onnxruntime: onnx:DIR."""
    from conceptfusion.perception.clip_onnx import OnnxClipEncoder

    return OnnxClipEncoder(_need_arg("onnx", arg, "dir"))


def _embedded(arg: str | None):
    """Embedded image tower (ONNX) aligned to the MiniLM text tower: embedded (shipped) or embedded:DIR."""
    from conceptfusion.perception.image_tower import SHIPPED_TOWER_DIR, EmbeddedEncoder
    from conceptfusion.perception.text_tower import MiniLMTextEncoder

    tower_dir = SHIPPED_TOWER_DIR if arg is None else _need_arg("embedded", arg, "dir")
    return EmbeddedEncoder(tower_dir, MiniLMTextEncoder())


def _embedded_v2(arg: str | None):
    """Embedded image tower trained on the object library (shipped v2 weights): embedded-v2."""
    from conceptfusion.perception.image_tower import SHIPPED_TOWER_V2_DIR, EmbeddedEncoder
    from conceptfusion.perception.text_tower import MiniLMTextEncoder

    _no_arg("embedded-v2", arg)
    return EmbeddedEncoder(SHIPPED_TOWER_V2_DIR, MiniLMTextEncoder())


def _audio_onnx(arg: str | None):
    """Audio-language encoder exported to ONNX: audio-onnx:DIR."""
    from conceptfusion.perception.audio import OnnxAudioEncoder

    return OnnxAudioEncoder(_need_arg("audio-onnx", arg, "dir"))


ENCODERS: dict[str, Callable[[str | None], object]] = {
    "color": _color,
    "minilm-text": _minilm,
    "hf": _hf,
    "onnx": _onnx,
    "audio-onnx": _audio_onnx,
}
"""Encoder name -> factory taking the spec's argument (``None`` when the spec has none)."""

if importlib.util.find_spec("conceptfusion.perception.image_tower") is not None:
    ENCODERS["embedded"] = _embedded
    ENCODERS["embedded-v2"] = _embedded_v2


RESERVED_ENCODER_NAMES = frozenset({"oracle", "oracle-open"})
"""Names a spec may start with that are not in :data:`ENCODERS` (privileged ground-truth
perception, :mod:`conceptfusion.perception.featurizer`): no encoder can be registered under them."""

ENCODER_NAME_PATTERN = re.compile(r"[a-z0-9][a-z0-9_.-]*")
"""What a registered name looks like: lower case letters, digits, ``-``, ``_`` and ``.``, starting
with a letter or digit. A spec is ``NAME`` or ``NAME:ARGUMENT``, its name matched in lower case
with spaces stripped, so a name with ``:``, spaces or capitals could never be asked for."""


def _check_encoder_name(name) -> str:
    if not isinstance(name, str):
        raise TypeError(f"register_encoder: name: expected a string such as 'my-clip', got {type(name).__name__} {name!r}")
    if not ENCODER_NAME_PATTERN.fullmatch(name):
        hint = f"; {name.strip().lower()!r} would do" if ENCODER_NAME_PATTERN.fullmatch(name.strip().lower()) else ""
        if ":" in name:
            hint = f"; ':' separates a spec's name from its argument (the factory receives {name.partition(':')[2]!r} as it)"
        raise ValueError(f"register_encoder: name: expected lower case letters, digits, '-', '_' or '.' "
                         f"(starting with a letter or digit), got {name!r}{hint}")
    if name in RESERVED_ENCODER_NAMES:
        raise ValueError(f"register_encoder: name {name!r} is reserved for privileged ground-truth perception "
                         f"({', '.join(sorted(RESERVED_ENCODER_NAMES))}); choose another name")
    return name


def _takes_one_argument(factory: Callable) -> bool | None:
    """Whether ``factory(arg)`` binds (None: its signature cannot be read, a builtin)."""
    try:
        inspect.signature(factory).bind(None)
    except TypeError:
        return False
    except ValueError:
        return None
    return True


def register_encoder(name: str, factory: Callable[[str | None], object], *, description: str = "",
                     replace: bool = False) -> None:
    """Add your own encoder to :data:`ENCODERS`, so that ``--encoder NAME`` (every suite, agent and
    ``cfharness view``), :func:`make_encoder` and ``cfharness list`` know it.

    ``factory(arg)`` builds the encoder, ``arg`` being the text after ``:`` in the spec (``None``
    for a bare ``NAME``). What it builds needs ``dim`` (an int), ``encode_text(texts)`` and,
    unless it embeds text only, ``encode_image(images)``, each returning one unit row of ``dim``
    float32 numbers per input (:class:`~conceptfusion.perception.encoders.Encoder`). It is handed
    out behind a checking wrapper (:func:`~conceptfusion.perception.checked.checked_encoder`): a
    call answering another shape, a NaN or inf, or rows off the unit sphere raises
    :class:`~conceptfusion.errors.EncoderOutputError` naming what was expected and what arrived.

    Example::

        from conceptfusion import register_encoder

        register_encoder("mine", lambda arg: MyEncoder(checkpoint=arg), description="my CLIP fine-tune")
        # cfharness run --import mymodule --encoder mine:/path/to/ckpt --suite rearrange

    Args:
        name: the spec name: lower case letters, digits, ``-``, ``_``, ``.`` (:data:`ENCODER_NAME_PATTERN`);
            not ``oracle`` or ``oracle-open``.
        factory: callable taking the spec's argument (``str`` or ``None``) and returning an encoder.
        description: one line for ``cfharness list`` (default: the factory's docstring, else its name).
        replace: allow replacing an encoder already registered under ``name`` (a built-in one too).

    Raises:
        TypeError: ``name`` or ``description`` is not a string; ``factory`` is not callable or
            cannot be called with one argument.
        ValueError: a name specs cannot ask for, a reserved name, or a name already registered
            without ``replace=True``.
    """
    _check_encoder_name(name)
    if not isinstance(description, str):
        raise TypeError(f"register_encoder: description: expected a string, got {type(description).__name__}")
    if not callable(factory):
        raise TypeError(f"register_encoder({name!r}): factory: expected a callable taking the spec's argument "
                        f"(str or None) and returning an encoder, got {type(factory).__name__} {factory!r:.80}")
    if _takes_one_argument(factory) is False:
        label = getattr(factory, "__qualname__", type(factory).__name__)
        raise TypeError(f"register_encoder({name!r}): factory: expected a callable taking one argument (the text after "
                        f"':' in the spec, or None), got {label}{inspect.signature(factory)}; wrap it: "
                        f"lambda arg: {label}()")
    if name in ENCODERS and not replace:
        raise ValueError(f"register_encoder: encoder {name!r} is already registered; choose another name or pass replace=True")
    from conceptfusion.perception.checked import checked_encoder

    def build(arg: str | None):
        return checked_encoder(name, factory(arg))

    own_doc = factory.__doc__ if inspect.isfunction(factory) or inspect.isclass(factory) else None
    doc = (description.strip() or (own_doc or "").strip()).splitlines()
    label = f"{getattr(factory, '__module__', '?')}.{getattr(factory, '__qualname__', type(factory).__name__)}"
    build.__doc__ = doc[0] if doc else f"user encoder ({label})"
    build.__qualname__ = build.__name__ = f"registered_{name}"
    ENCODERS[name] = build
    _AVAILABLE.pop(name, None)  # a replaced built-in's file check is not the new encoder's


def parse_encoder_spec(spec: str) -> tuple[str, str | None]:
    """Split ``"NAME:ARGUMENT"`` into ``(name, argument)``; ``argument`` is ``None`` without a colon.

    Raises:
        TypeError: ``spec`` is not a string.
        ValueError: the name is empty or unknown (with the nearest valid names).
    """
    if not isinstance(spec, str):
        raise TypeError(f"encoder spec: expected a string such as 'hf:openai/clip-vit-base-patch32', got {type(spec).__name__}")
    name, sep, arg = spec.strip().partition(":")
    name = name.strip().lower()
    if name not in ENCODERS:
        listing = f"encoders: {', '.join(sorted(ENCODERS))}"
        if "/" in spec and not sep:
            listing += f"; a model needs a prefix: hf:{spec.strip()} for Hugging Face, onnx:{spec.strip()} for an ONNX folder"
        raise unknown_name_error("encoder", name, sorted(ENCODERS), cutoff=0.5, listing=listing)
    return name, (arg if sep else None)


def make_encoder(spec: str):
    """Build the encoder a spec names (see the module docstring for the table).

    Example::

        from conceptfusion import make_encoder

        enc = make_encoder("color")                  # or "embedded", "hf:openai/clip-vit-base-patch32"
        text_nd = enc.encode_text(["red", "blue"])   # (2, enc.dim) float32, unit rows

    Raises:
        ValueError: unknown name (with the nearest valid names) or a missing/extra argument.
        FileNotFoundError, CheckpointError, MissingDependencyError: from the encoder itself.
    """
    name, arg = parse_encoder_spec(spec)
    return ENCODERS[name](arg)


def _hf_available(arg: str | None) -> None:
    """A local checkpoint folder with its config and weights, or a hub id in the local Hugging Face
    cache; nothing is looked up online (a run fetches no model: download it first)."""
    from conceptfusion.perception.clip_hf import check_checkpoint_folder, resolve_source

    ref, local = resolve_source(_need_arg("hf", arg, "hub id or dir"))
    if local:
        check_checkpoint_folder(Path(ref))
        return
    try:
        from huggingface_hub import constants, try_to_load_from_cache
    except ImportError:  # transformers brings huggingface_hub: HFClipEncoder names the extra to install
        return
    if isinstance(try_to_load_from_cache(ref, "config.json"), str):
        return
    raise FileNotFoundError(f"hf:{ref}: expected a model in the local Hugging Face cache ({constants.HF_HUB_CACHE}) or a "
                            f"checkpoint folder (hf:/path/to/dir), found neither; nothing is downloaded during a run: "
                            f"fetch it first (huggingface-cli download {ref})")


def _onnx_available(arg: str | None) -> None:
    from conceptfusion.perception.clip_onnx import check_onnx_folder

    check_onnx_folder(_need_arg("onnx", arg, "dir"))


def _folder_available(name: str):
    def check(arg: str | None) -> None:
        if arg is None:  # the shipped weights
            return
        d = Path(_need_arg(name, arg, "dir")).expanduser()
        if not d.is_dir():
            raise FileNotFoundError(f"{name}:{arg}: expected a folder of {name} weights, no folder is there")
    return check


_AVAILABLE: dict[str, Callable[[str | None], None]] = {
    "hf": _hf_available, "onnx": _onnx_available, "embedded": _folder_available("embedded"),
    "audio-onnx": _folder_available("audio-onnx"),
}
"""Encoder name -> a cheap check that its weights are there (loads nothing)."""


def check_encoder_files(spec: str) -> None:
    """Check, before anything runs, that the encoder a spec names can be loaded: a folder argument
    exists with the files the encoder needs, a Hugging Face hub id is in the local cache; loads no
    weights and touches no network.

    Raises:
        ValueError: as :func:`parse_encoder_spec`, or a missing argument.
        FileNotFoundError: the folder, a file in it or the hub id is not there (naming it).
        CheckpointError: a checkpoint folder without its config or weights.
    """
    name, arg = parse_encoder_spec(spec)
    check = _AVAILABLE.get(name)
    if check is not None:
        check(arg)


def describe_encoders() -> dict[str, str]:
    """One line per registered encoder name, for ``--help`` texts."""
    return {name: (factory.__doc__ or "").strip().splitlines()[0] for name, factory in sorted(ENCODERS.items())}
