"""Opening the headless OpenGL context, or saying in one line what is missing."""

from __future__ import annotations

INSTALL_HINT = "apt-get install libegl1 libgl1-mesa-dri libegl-mesa0"


class GLUnavailable(RuntimeError):
    """No headless OpenGL context: moderngl, libEGL or a Mesa driver is missing (one line)."""


def open_context():
    """A headless moderngl context on EGL (Mesa llvmpipe without a GPU); GLUnavailable, with
    what is missing and how to install it, when none can be made. The C libraries' own
    warnings on stderr are caught (:func:`csm_assets.cstderr.captured`, serialized with the
    image writers' captures) and folded into that one line."""
    from ..cstderr import captured

    try:
        import moderngl
    except ImportError as e:
        raise GLUnavailable(f"no OpenGL: the Python package moderngl cannot be imported ({e}); "
                            f"pip install moderngl") from None
    with captured() as err:
        try:
            ctx = moderngl.create_standalone_context(backend="egl")
            problem = None
        except Exception as e:  # glcontext raises plain Exceptions
            ctx, problem = None, str(e).strip() or type(e).__name__
    said = "".join(err).strip()
    if ctx is None:
        detail = "; ".join(x for x in (problem, said.splitlines()[0] if said else "") if x)
        raise GLUnavailable(f"no headless OpenGL (EGL) context: {detail.replace(chr(10), ' ')}; install "
                            f"the EGL loader and Mesa's drivers: {INSTALL_HINT}")
    return ctx  # (notes the libraries printed while a context came are dropped)


def check_texture_size(ctx, shape, where) -> None:
    """FormatError naming ``where`` (the file) when a texture of ``shape`` (``(H, W, ...)``) is
    wider or taller than ``ctx`` can sample (its GL_MAX_TEXTURE_SIZE: 16384 on Mesa llvmpipe),
    before any upload (which would fail with GL_INVALID_VALUE)."""
    from ..errors import FormatError

    limit = int(ctx.info["GL_MAX_TEXTURE_SIZE"])
    if max(shape[:2]) > limit:
        raise FormatError(where, f"a {shape[1]}x{shape[0]} step map is larger than this OpenGL "
                                 f"({ctx.info.get('GL_RENDERER', '?')}) can sample: at most {limit} texels a side "
                                 f"(GL_MAX_TEXTURE_SIZE), so it cannot be drawn here (the map itself is fine)")
