"""`autochair certs`: a CA, the chair's server certificate and laptops' client certificates.

A laptop's role is its certificate's common name (`autochair-drive` or `autochair-view`, see
autochair.deploy.ROLE_CN), which the chair's access control matches; the laptop's own name is
the OU and a DNS SAN. Keys are ECDSA P-256, PEM (PKCS#8), private keys mode 0600.

Nothing secret is ever overwritten without `--force`: an existing CA (ca.pem + ca-key.pem) is
reused, and so is an existing private key of the chair or a laptop (its certificate is issued
again with it); a reused key readable by others is set back to 0600. A half CA (one of the two
files), a key that cannot be read or a CA key that does not match ca.pem is an error naming the
file; `--force` makes new ones (a new CA: every laptop then needs a new certificate).
"""

from __future__ import annotations

import argparse
import datetime as dt
import ipaddress
import os
import stat
import sys
from pathlib import Path
from typing import Any

from autochair.cli import CliError

DAYS = 3650


def register(sub: Any) -> None:
    p: argparse.ArgumentParser = sub.add_parser(
        "certs", help="make a CA and certificates for the chair and laptops",
        description="Create (or reuse) OUT/ca.pem, make OUT/chair.pem for the chair's TLS "
        "listener and OUT/<laptop>.pem + OUT/<laptop>.json5 (Zenoh profile) per laptop.")
    p.add_argument("--out", default="certs", help="directory (default: certs)")
    p.add_argument("--chair-name", action="append", default=[], metavar="NAME",
                   help="extra DNS name or IP of the chair (127.0.0.1 and localhost always)")
    p.add_argument("--laptop", action="append", default=[], metavar="NAME:ROLE",
                   help="a laptop and its role, drive or view; repeatable")
    p.add_argument("--connect", default="tls/chair.local:7448",
                   help="chair endpoint written into laptop profiles")
    p.add_argument("--force", action="store_true",
                   help="replace an existing CA and private keys with new ones (default: "
                   "reuse them, never overwrite)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    out = Path(args.out)
    laptops = []
    for item in args.laptop:
        name, _, role = item.partition(":")
        if role not in ("drive", "view") or not name.replace("-", "").replace("_", "").isalnum():
            raise CliError(f"--laptop wants NAME:drive or NAME:view (NAME alphanumeric), "
                           f"got {item!r}")
        laptops.append((name, role))
    notes: list[str] = []
    written = make_all(out, args.chair_name, laptops, args.connect, force=args.force,
                       notes=notes)
    for note in notes:
        print(note, file=sys.stderr)
    for path in written:
        print(path)
    return 0


def make_all(out: Path, chair_names: list[str], laptops: list[tuple[str, str]],
             connect: str, *, force: bool = False, notes: list[str] | None = None
             ) -> list[Path]:
    """Make (or reuse) the CA, the chair's and the laptops' certificates. Without `force` no
    existing CA file or private key is overwritten (CliError instead); `notes` gets a line per
    reused key whose permissions were fixed."""
    from autochair import deploy

    out.mkdir(parents=True, exist_ok=True)
    notes = notes if notes is not None else []
    written: list[Path] = []
    new_ca = force or not all(os.path.lexists(out / f) for f in ("ca.pem", "ca-key.pem"))
    # A new CA needs a new chair certificate too: the old one would not verify.
    issue_chair = bool(chair_names) or new_ca or not (out / "chair.pem").exists()
    if not force:  # every refusal before anything is written
        for stem in ["chair"] * issue_chair + [name for name, _ in laptops]:
            if os.path.lexists(out / f"{stem}-key.pem"):
                _read_key(out / f"{stem}-key.pem")
    ca_key, ca_cert = _load_or_make_ca(out, written, force, notes)
    if issue_chair:
        names = ["localhost", "127.0.0.1", *chair_names]
        written += issue(out, "chair", "autochair-chair", names, server=True,
                         ca_key=ca_key, ca_cert=ca_cert, force=force, notes=notes)
    else:
        _reused_key(out / "chair-key.pem", notes)
    for name, role in laptops:
        written += issue(out, name, deploy.ROLE_CN[role], [name], server=False,
                         ca_key=ca_key, ca_cert=ca_cert, force=force, notes=notes)
        profile = out / f"{name}.json5"
        profile.write_text(deploy.json5(
            deploy.laptop_zenoh(str(out.resolve()), name, connect),
            f"Laptop {name} ({role}): `autochair monitor --zenoh-config {profile.name}`"))
        written.append(profile)
    return written


def _refuse(path: Path, what: str) -> CliError:
    return CliError(f"{path}: {what}; refusing to overwrite it (pass --force to replace it)")


def _reused_key(path: Path, notes: list[str]) -> None:
    """A private key kept as it is: readable by its owner only (0600 if it was looser)."""
    if not path.exists():
        return
    mode = stat.S_IMODE(path.stat().st_mode)
    if mode & 0o077:
        path.chmod(0o600)
        notes.append(f"{path}: permissions were {mode:04o}, now 0600 (a private key)")


def _read_key(path: Path) -> Any:
    from cryptography.exceptions import UnsupportedAlgorithm
    from cryptography.hazmat.primitives import serialization

    try:
        return serialization.load_pem_private_key(path.read_bytes(), None)
    except (OSError, ValueError, TypeError, UnsupportedAlgorithm) as e:
        raise _refuse(path, f"an existing private key that cannot be read ({e})") from None


def _load_key(path: Path, notes: list[str]) -> Any:
    key = _read_key(path)
    _reused_key(path, notes)
    return key


def _public_der(key: Any) -> bytes:
    from cryptography.hazmat.primitives import serialization

    return bytes(key.public_bytes(serialization.Encoding.DER,
                                  serialization.PublicFormat.SubjectPublicKeyInfo))


def _load_or_make_ca(out: Path, written: list[Path], force: bool,
                     notes: list[str]) -> tuple[Any, Any]:
    from cryptography import x509

    key_path, cert_path = out / "ca-key.pem", out / "ca.pem"
    have_key, have_cert = os.path.lexists(key_path), os.path.lexists(cert_path)
    if (have_key or have_cert) and not force:
        if not have_key:
            raise _refuse(cert_path, f"a CA certificate without its key {key_path.name}")
        if not have_cert:
            raise _refuse(key_path, f"a CA key without its certificate {cert_path.name}")
        key = _load_key(key_path, notes)
        try:
            cert = x509.load_pem_x509_certificate(cert_path.read_bytes())
        except (OSError, ValueError) as e:
            raise _refuse(cert_path, f"a CA certificate that cannot be read ({e})") from None
        if _public_der(cert.public_key()) != _public_der(key.public_key()):
            raise _refuse(key_path, f"a CA key that does not match {cert_path.name}")
        return key, cert
    key = _new_key()
    name = _name("autochair CA", "")
    cert = _builder(name, name, key.public_key(), DAYS).add_extension(
        x509.BasicConstraints(ca=True, path_length=0), critical=True).add_extension(
        x509.KeyUsage(digital_signature=True, key_cert_sign=True, crl_sign=True,
                      content_commitment=False, key_encipherment=False, data_encipherment=False,
                      key_agreement=False, encipher_only=False, decipher_only=False),
        critical=True).sign(key, _sha256())
    written += _save(out, "ca", key, cert, new_key=True)
    return key, cert


def issue(out: Path, stem: str, cn: str, names: list[str], *, server: bool, ca_key: Any,
          ca_cert: Any, force: bool = False, notes: list[str] | None = None) -> list[Path]:
    """Write OUT/<stem>.pem signed by the CA, for the key in OUT/<stem>-key.pem: the existing
    one (reused, never overwritten) unless `force` or there is none."""
    from cryptography import x509
    from cryptography.x509.oid import ExtendedKeyUsageOID

    key_path = out / f"{stem}-key.pem"
    reuse = os.path.lexists(key_path) and not force
    key = _load_key(key_path, notes if notes is not None else []) if reuse else _new_key()
    sans: list[x509.GeneralName] = []
    for n in names:
        try:
            sans.append(x509.IPAddress(ipaddress.ip_address(n)))
        except ValueError:
            sans.append(x509.DNSName(n))
    usage = ExtendedKeyUsageOID.SERVER_AUTH if server else ExtendedKeyUsageOID.CLIENT_AUTH
    cert = (_builder(_name(cn, "" if server else stem), ca_cert.subject, key.public_key(), DAYS)
            .add_extension(x509.BasicConstraints(ca=False, path_length=None), critical=True)
            .add_extension(x509.SubjectAlternativeName(sans), critical=False)
            .add_extension(x509.ExtendedKeyUsage([usage]), critical=False)
            .sign(ca_key, _sha256()))
    return _save(out, stem, key, cert, new_key=not reuse)


def _new_key() -> Any:
    from cryptography.hazmat.primitives.asymmetric import ec

    return ec.generate_private_key(ec.SECP256R1())


def _sha256() -> Any:
    from cryptography.hazmat.primitives import hashes

    return hashes.SHA256()


def _name(cn: str, ou: str) -> Any:
    from cryptography import x509
    from cryptography.x509.oid import NameOID

    attrs = [x509.NameAttribute(NameOID.ORGANIZATION_NAME, "autochair")]
    if ou:
        attrs.append(x509.NameAttribute(NameOID.ORGANIZATIONAL_UNIT_NAME, ou))
    attrs.append(x509.NameAttribute(NameOID.COMMON_NAME, cn))
    return x509.Name(attrs)


def _builder(subject: Any, issuer: Any, public_key: Any, days: int) -> Any:
    from cryptography import x509

    now = dt.datetime.now(dt.UTC)
    return (x509.CertificateBuilder().subject_name(subject).issuer_name(issuer)
            .public_key(public_key).serial_number(x509.random_serial_number())
            .not_valid_before(now - dt.timedelta(minutes=5))
            .not_valid_after(now + dt.timedelta(days=days)))


def _save(out: Path, stem: str, key: Any, cert: Any, *, new_key: bool) -> list[Path]:
    """Write the certificate, and the key when it is new: created 0600 from the start (an
    old file in the way, only there with --force, is removed first, never written through)."""
    from cryptography.hazmat.primitives import serialization

    key_path, cert_path = out / f"{stem}-key.pem", out / f"{stem}.pem"
    if new_key:
        if os.path.lexists(key_path):
            key_path.unlink()
        fd = os.open(key_path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
        with os.fdopen(fd, "wb") as f:
            f.write(key.private_bytes(serialization.Encoding.PEM,
                                      serialization.PrivateFormat.PKCS8,
                                      serialization.NoEncryption()))
    cert_path.write_bytes(cert.public_bytes(serialization.Encoding.PEM))
    return [cert_path, key_path] if new_key else [cert_path]

