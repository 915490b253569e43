"""Hazard: `autochair certs` destroying the chair's trust root or a private key. Re-running it
(to add a laptop or a chair name) reuses the CA and every existing key; nothing secret is
overwritten without --force (one-line error naming the file and --force instead); a reused key
readable by others is set back to 0600; new keys are 0600 from creation."""

from __future__ import annotations

import stat
from pathlib import Path

import pytest
from cryptography import x509
from cryptography.exceptions import InvalidSignature
from cryptography.hazmat.primitives import serialization

from autochair.cli import main

LAPTOPS = ["--laptop", "alice:drive", "--laptop", "bob:view"]
KEYS = ["ca-key.pem", "chair-key.pem", "alice-key.pem", "bob-key.pem"]


def certs(out: Path, *extra: str) -> int:
    return main(["certs", "--out", str(out), "--connect", "tls/127.0.0.1:1", *LAPTOPS, *extra])


def mode(p: Path) -> int:
    return stat.S_IMODE(p.stat().st_mode)


def files(out: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(out.iterdir())}


def public(pem: bytes) -> bytes:
    key = serialization.load_pem_private_key(pem, None)
    return key.public_key().public_bytes(serialization.Encoding.DER,
                                         serialization.PublicFormat.SubjectPublicKeyInfo)


def cert_public(path: Path) -> bytes:
    return x509.load_pem_x509_certificate(path.read_bytes()).public_key().public_bytes(
        serialization.Encoding.DER, serialization.PublicFormat.SubjectPublicKeyInfo)


def signed_by_ca(out: Path, name: str) -> bool:
    ca = x509.load_pem_x509_certificate((out / "ca.pem").read_bytes())
    cert = x509.load_pem_x509_certificate((out / f"{name}.pem").read_bytes())
    try:
        cert.verify_directly_issued_by(ca)
    except (ValueError, TypeError, InvalidSignature):
        return False
    return True


def test_rerun_reuses_the_ca_and_every_key(tmp_path: Path) -> None:
    out = tmp_path / "certs"
    assert certs(out) == 0
    for k in KEYS:
        assert mode(out / k) == 0o600, k
    first = files(out)
    assert certs(out, "--chair-name", "chair.local", "--laptop", "carol:view") == 0
    again = files(out)
    for k in ["ca.pem", *KEYS]:
        assert again[k] == first[k], f"{k} was rewritten"
    assert again["chair.pem"] != first["chair.pem"]  # re-issued (new name) with the same key
    for name in ("chair", "alice", "bob", "carol"):
        assert signed_by_ca(out, name)
        assert cert_public(out / f"{name}.pem") == public((out / f"{name}-key.pem").read_bytes())
    assert mode(out / "carol-key.pem") == 0o600


def test_reused_keys_get_0600_back(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "certs"
    assert certs(out) == 0
    (out / "ca-key.pem").chmod(0o644)
    (out / "alice-key.pem").chmod(0o640)
    (out / "chair-key.pem").chmod(0o604)
    capsys.readouterr()
    assert certs(out) == 0
    err = capsys.readouterr().err
    for k in KEYS:
        assert mode(out / k) == 0o600, k
    assert "ca-key.pem: permissions were 0644, now 0600" in err
    assert "alice-key.pem: permissions were 0640" in err
    assert "chair-key.pem: permissions were 0604" in err
    assert "bob-key.pem" not in err  # control: a key that was 0600 is left alone, no note


@pytest.mark.parametrize("missing,named", [("ca-key.pem", "ca.pem"), ("ca.pem", "ca-key.pem")])
def test_half_a_ca_is_refused_without_force(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                            missing: str, named: str) -> None:
    out = tmp_path / "certs"
    assert certs(out) == 0
    (out / missing).unlink()
    before = files(out)
    capsys.readouterr()
    assert certs(out) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and err.startswith(f"autochair certs: error: {out / named}:")
    assert "refusing to overwrite" in err and "--force" in err
    assert files(out) == before  # nothing written at all
    # --force makes a new CA; the other keys are new too.
    assert certs(out, "--force") == 0
    after = files(out)
    assert after[named] != before[named] and (out / missing).exists()
    assert after["alice-key.pem"] != before["alice-key.pem"]
    for k in KEYS:
        assert mode(out / k) == 0o600, k
    assert signed_by_ca(out, "alice") and signed_by_ca(out, "chair")


def test_unreadable_key_is_refused_and_force_replaces_it_0600(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "certs"
    assert certs(out) == 0
    bad = out / "alice-key.pem"
    bad.write_bytes(b"-----BEGIN PRIVATE KEY-----\ntorn\n")
    bad.chmod(0o644)
    before = files(out)
    capsys.readouterr()
    assert certs(out) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith(f"autochair certs: error: {bad}: an existing private key that "
                          "cannot be read") and "--force" in err and "\n" not in err
    assert bad.read_bytes() == before["alice-key.pem"] and files(out)["ca.pem"] == before["ca.pem"]
    assert certs(out, "--force") == 0
    # A key file that existed 0644 is replaced by a new file 0600, not written through.
    assert mode(bad) == 0o600
    assert cert_public(out / "alice.pem") == public(bad.read_bytes())


def test_ca_key_that_does_not_match_the_ca_is_refused(tmp_path: Path,
                                                      capsys: pytest.CaptureFixture[str]) -> None:
    out, other = tmp_path / "certs", tmp_path / "other"
    assert certs(out) == 0 and certs(other) == 0
    (out / "ca-key.pem").write_bytes((other / "ca-key.pem").read_bytes())
    before = files(out)
    capsys.readouterr()
    assert certs(out) == 2
    err = capsys.readouterr().err
    assert f"{out / 'ca-key.pem'}: a CA key that does not match ca.pem" in err
    assert files(out) == before
