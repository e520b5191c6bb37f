"""Regenerate `fdir_service/mavlink/generated/fdir.py` from `fdir.xml` with pymavlink's mavgen.

`fdir.xml` includes `common.xml`; the include is resolved against the copy of common.xml (and
its own includes) shipped with the installed pymavlink, so the generated module always matches
the pymavlink in use. Run: `python -m fdir_service.mavlink.regenerate [--check]`.
"""

from __future__ import annotations

import argparse
import shutil
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
DIALECT_XML = HERE / "fdir.xml"
GENERATED = HERE / "generated" / "fdir.py"


def _pymavlink_definitions() -> Path:
    import pymavlink

    return Path(pymavlink.__file__).resolve().parent / "dialects" / "v20"


def generate(output: Path, xml_text: str | None = None) -> Path:
    """Run mavgen (Python, MAVLink 2, validated) on fdir.xml (or on `xml_text`, another version of
    it: tests build an older decoder); write the module to `output`."""
    from pymavlink.generator import mavgen

    defs = _pymavlink_definitions()
    with tempfile.TemporaryDirectory() as tmp:
        tmpdir = Path(tmp)
        for name in ("common.xml", "standard.xml", "minimal.xml"):
            shutil.copy(defs / name, tmpdir / name)
        xml = tmpdir / "fdir.xml"
        if xml_text is None:
            shutil.copy(DIALECT_XML, xml)
        else:
            xml.write_text(xml_text)
        out_base = tmpdir / "fdir"
        opts = mavgen.Opts(str(out_base), wire_protocol="2.0", language="Python3", validate=True)
        if not mavgen.mavgen(opts, [str(xml)]):
            raise RuntimeError("mavgen failed on fdir.xml")
        produced = tmpdir / "fdir.py"
        output.parent.mkdir(parents=True, exist_ok=True)
        shutil.copy(produced, output)
    return output


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--check", action="store_true",
                    help="do not write; exit 1 if the committed module differs from a fresh generation")
    args = ap.parse_args(argv)
    if args.check:
        with tempfile.TemporaryDirectory() as tmp:
            fresh = generate(Path(tmp) / "fdir.py")
            same = fresh.read_bytes() == GENERATED.read_bytes()
        print("generated module is up to date" if same else "generated module is stale: regenerate")
        return 0 if same else 1
    generate(GENERATED)
    print(f"wrote {GENERATED}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
