"""OS errors in words: one line naming the path(s) and the reason.
"""

from __future__ import annotations

import errno


def describe_os_error(error: OSError) -> str:
    """The reason an OS call failed on a path, in words (errno-specific where it matters:
    "no space left on the device", ...)."""
    reasons = {errno.ENOENT: "not found", errno.ELOOP: "is a symbolic link loop",
               errno.ENAMETOOLONG: "file name too long", errno.EACCES: "permission denied",
               errno.EPERM: "operation not permitted", errno.ENOTDIR: "a parent is not a "
               "directory", errno.EISDIR: "is a directory", errno.ENOSPC: "no space left on "
               "the device", errno.EROFS: "read-only file system", errno.EDQUOT: "disk quota "
               "exceeded", errno.EIO: "input/output error", errno.EFBIG: "file too large",
               errno.EEXIST: "already exists", errno.EMFILE: "too many open files"}
    return reasons.get(error.errno or 0) or " ".join((error.strerror or str(error)).split())


def os_error_line(exc: OSError) -> str:
    """One line for an OS error: the path (both, for a rename) and the reason."""
    paths = [str(p) for p in (exc.filename, exc.filename2) if p is not None]
    reason = describe_os_error(exc)
    return f"{' → '.join(paths)}: {reason}" if paths else reason
