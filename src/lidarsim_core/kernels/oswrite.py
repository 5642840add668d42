"""Files written atomically by a compiled loop with the interpreter lock released.

:func:`write_files` does for a few files what :func:`lidarsim_core.base.atomic.write_bytes_atomic`
does for one (a hidden temporary file opened with ``O_EXCL``, written, synced unless the sync
is deferred, closed and renamed onto its target), calling the C library through the
addresses :func:`lidarsim_core.base.libc.file_functions` gives, so a dataset's writer thread
makes a frame's ten system calls without taking the interpreter lock back between them.

It only handles the common case, a target that does not exist yet: it stops before the first
file whose target is there (or cannot be checked), and at the first call that fails, after
removing that file's temporary file, and says how many files it finished. The caller writes
the rest the usual way, whose checks and one-line errors then apply unchanged.
"""

from __future__ import annotations

from llvmlite import ir
from numba import njit, types
from numba.extending import intrinsic

# the kernel's indices into lidarsim_core.base.libc.NAMES
_OPEN, _WRITE, _CLOSE, _RENAME, _UNLINK, _FSYNC, _FACCESSAT, _ERRNO = range(8)

_I32 = ir.IntType(32)
_I64 = ir.IntType(64)
_PTR = ir.IntType(8).as_pointer()
_TYPES = {"i": _I32, "l": _I64, "p": _PTR}


def _codegen(result: str, params: str):  # noqa: ANN202
    """A call of the C function at the first argument's address: ``params`` are the C types
    of the others (``i`` int, ``l`` 64-bit integer, ``p`` pointer), each given as an int64;
    ``result`` the C type returned (widened to int64)."""
    def codegen(context, builder, sig, args):  # noqa: ANN001, ANN202
        fnty = ir.FunctionType(_TYPES[result], [_TYPES[p] for p in params])
        callee = builder.inttoptr(args[0], fnty.as_pointer())
        values = [builder.inttoptr(v, _PTR) if p == "p" else
                  builder.trunc(v, _I32) if p == "i" else v for v, p in zip(args[1:], params)]
        out = builder.call(callee, values)
        return builder.sext(out, _I64) if result == "i" else out
    return codegen


def _integers(*arguments) -> bool:  # noqa: ANN002
    return all(isinstance(t, types.Integer) for t in arguments)


@intrinsic
def _call_i(typingctx, function, a):  # noqa: ANN001, ANN202
    """``int f(int)``: ``close``, ``fsync``."""
    if not _integers(function, a):
        return None
    return types.int64(types.int64, types.int64), _codegen("i", "i")


@intrinsic
def _call_p(typingctx, function, a):  # noqa: ANN001, ANN202
    """``int f(const char *)``: ``unlink``."""
    if not _integers(function, a):
        return None
    return types.int64(types.int64, types.int64), _codegen("i", "p")


@intrinsic
def _call_pp(typingctx, function, a, b):  # noqa: ANN001, ANN202
    """``int f(const char *, const char *)``: ``rename``."""
    if not _integers(function, a, b):
        return None
    return types.int64(types.int64, types.int64, types.int64), _codegen("i", "pp")


@intrinsic
def _call_pii(typingctx, function, a, b, c):  # noqa: ANN001, ANN202
    """``int f(const char *, int, int)``: ``open`` with its mode."""
    if not _integers(function, a, b, c):
        return None
    return types.int64(types.int64, types.int64, types.int64, types.int64), \
        _codegen("i", "pii")


@intrinsic
def _call_ipl(typingctx, function, a, b, c):  # noqa: ANN001, ANN202
    """``ssize_t f(int, const void *, size_t)``: ``write``."""
    if not _integers(function, a, b, c):
        return None
    return types.int64(types.int64, types.int64, types.int64, types.int64), \
        _codegen("l", "ipl")


@intrinsic
def _call_ipii(typingctx, function, a, b, c, d):  # noqa: ANN001, ANN202
    """``int f(int, const char *, int, int)``: ``faccessat``."""
    if not _integers(function, a, b, c, d):
        return None
    return types.int64(types.int64, types.int64, types.int64, types.int64, types.int64), \
        _codegen("i", "ipii")


@intrinsic
def _errno(typingctx, function):  # noqa: ANN001, ANN202
    """``*__errno_location()``: this thread's ``errno``."""
    if not _integers(function):
        return None

    def codegen(context, builder, sig, args):  # noqa: ANN001, ANN202
        fnty = ir.FunctionType(_I32.as_pointer(), [])
        location = builder.call(builder.inttoptr(args[0], fnty.as_pointer()), [])
        return builder.sext(builder.load(location), _I64)

    return types.int64(types.int64), codegen


#: Where :func:`write_files`' plan holds each option, then the number of files and where
#: the first file's four numbers start (see the kernel's docstring).
PLAN_OPTIONS = ("sync", "flags", "mode", "at_fdcwd", "f_ok", "at_symlink_nofollow", "enoent",
                "eintr")
_SYNC, _FLAGS, _MODE, _AT_FDCWD, _F_OK, _NOFOLLOW, _ENOENT, _EINTR = range(8)
_COUNT = len(PLAN_OPTIONS)
_FIRST = _COUNT + 1


@njit(nogil=True, cache=True)
def write_files(functions, names, plan):  # noqa: ANN001, ANN201
    """Write ``plan[8]`` files, each atomically, in order.

    Parameters
    ----------
    functions
        The C functions' addresses (:func:`lidarsim_core.base.libc.file_functions`).
    names
        The files' NUL-terminated names, bytes.
    plan
        ``int64``: the options of :data:`PLAN_OPTIONS` (whether to ``fsync`` each file
        before its rename, 0 or 1; ``open``'s flags; the new file's mode; ``AT_FDCWD``,
        ``F_OK``, ``AT_SYMLINK_NOFOLLOW``, ``ENOENT``, ``EINTR``), the number of files, then
        four numbers a file: where its temporary name and its target start in ``names``,
        and the address and length of its bytes (kept alive by the caller).

    Returns
    -------
    (int, int)
        How many files were written (renamed onto their targets), and the ``errno`` of the
        call that stopped at the next one (0 when its target exists, or when all were
        written). The stopped file's temporary file is removed; its target is untouched.
    """
    base = names.ctypes.data
    count = plan[_COUNT]
    for i in range(count):
        temporary = base + plan[_FIRST + 4 * i]
        target = base + plan[_FIRST + 4 * i + 1]
        data = plan[_FIRST + 4 * i + 2]
        size = plan[_FIRST + 4 * i + 3]
        if _call_ipii(functions[_FACCESSAT], plan[_AT_FDCWD], target, plan[_F_OK],
                      plan[_NOFOLLOW]) == 0:
            return i, 0  # there already: the caller's checks decide
        error = _errno(functions[_ERRNO])
        if error != plan[_ENOENT]:
            return i, error
        fd = _call_pii(functions[_OPEN], temporary, plan[_FLAGS], plan[_MODE])
        if fd < 0:
            return i, _errno(functions[_ERRNO])
        done = 0
        error = 0
        while done < size:
            written = _call_ipl(functions[_WRITE], fd, data + done, size - done)
            if written > 0:
                done += written
            elif written < 0 and _errno(functions[_ERRNO]) == plan[_EINTR]:
                continue
            else:  # an error, or no progress (which a regular file never makes)
                error = max(_errno(functions[_ERRNO]), 1)
                break
        if error == 0 and plan[_SYNC] != 0 and _call_i(functions[_FSYNC], fd) != 0:
            error = max(_errno(functions[_ERRNO]), 1)
        if _call_i(functions[_CLOSE], fd) != 0 and error == 0:
            error = max(_errno(functions[_ERRNO]), 1)
        if error == 0 and _call_pp(functions[_RENAME], temporary, target) != 0:
            error = max(_errno(functions[_ERRNO]), 1)
        if error != 0:
            _call_p(functions[_UNLINK], temporary)
            return i, error
    return count, 0
