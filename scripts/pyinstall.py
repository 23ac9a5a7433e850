"""Install the package `gonio` into a virtualenv from the extension module the tests'
cargo build made, as `pip install` of maturin's wheel lays it out.

maturin would compile the extension in its own cargo invocation, with gonio-py's
dependency features alone; the workspace's test build unifies features with the
dev-dependencies (serde's `alloc`, syn's `visit`, ...), so the two builds share almost
nothing and maturin recompiled half the tree (six minutes of a fresh scripts/test).
Installing the test build's library instead tests the very code `cargo test` tested.
The layout is the wheel's: `gonio/` (the Python sources and `_native.abi3.so`) and
`gonio-VERSION.dist-info` with METADATA and a RECORD, so `pip uninstall gonio` and
`importlib.metadata` work. `pip install ./crates/gonio-py` (maturin) stays the way a
user installs the package.

Usage: python pyinstall.py SITE_PACKAGES EXTENSION PACKAGE_DIR VERSION
"""

from __future__ import annotations

import base64
import hashlib
import shutil
import sys
from pathlib import Path

#: The wheel's METADATA fields (crates/gonio-py/pyproject.toml's [project]).
METADATA = """\
Metadata-Version: 2.1
Name: gonio
Version: {version}
Summary: Gonio from Python: measure, model and check BRDFs at Rust speed
Requires-Python: >=3.9
Requires-Dist: numpy>=1.22
Requires-Dist: pandas>=1.4
"""


def _record_line(root: Path, path: Path) -> str:
    data = path.read_bytes()
    digest = base64.urlsafe_b64encode(hashlib.sha256(data).digest()).rstrip(b"=")
    return f"{path.relative_to(root).as_posix()},sha256={digest.decode()},{len(data)}"


def _remove_previous(site: Path) -> None:
    for info in site.glob("gonio-*.dist-info"):
        shutil.rmtree(info)
    shutil.rmtree(site / "gonio", ignore_errors=True)


def install(site: Path, extension: Path, package: Path, version: str) -> None:
    """Replace any installed `gonio` in `site` with `package` and `extension`."""
    if not extension.is_file():
        raise SystemExit(
            f"pyinstall: {extension}: no extension module (build it first)"
        )
    _remove_previous(site)
    target = site / "gonio"
    shutil.copytree(
        package, target, ignore=shutil.ignore_patterns("__pycache__", "*.pyc")
    )
    # Copied to a temporary name and renamed: a half-written module never imports.
    tmp = target / "_native.abi3.so.tmp"
    shutil.copyfile(extension, tmp)
    tmp.rename(target / "_native.abi3.so")
    info = site / f"gonio-{version}.dist-info"
    info.mkdir()
    (info / "METADATA").write_text(METADATA.format(version=version))
    (info / "INSTALLER").write_text("gonio-scripts\n")
    files = sorted(p for p in [*target.rglob("*"), *info.iterdir()] if p.is_file())
    record = [_record_line(site, p) for p in files]
    record.append(f"{info.name}/RECORD,,")
    (info / "RECORD").write_text("\n".join(record) + "\n")


if __name__ == "__main__":
    if len(sys.argv) != 5:
        raise SystemExit(__doc__)
    site, ext, pkg, ver = sys.argv[1:]
    install(Path(site), Path(ext), Path(pkg), ver)
