"""`autochair certs`: a CA, the chair's server certificate and laptops' client certificates.

A laptop's role is its certificate's common name (`autochair-drive` or `autochair-view`, see
autochair.deploy.ROLE_CN), which the chair's access control matches; the laptop's own name is
the OU and a DNS SAN. Keys are ECDSA P-256, PEM (PKCS#8), private keys mode 0600.
"""

from __future__ import annotations

import argparse
import datetime as dt
import ipaddress
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
    for path in make_all(out, args.chair_name, laptops, args.connect):
        print(path)
    return 0


def make_all(out: Path, chair_names: list[str], laptops: list[tuple[str, str]],
             connect: str) -> list[Path]:
    from autochair import deploy

    out.mkdir(parents=True, exist_ok=True)
    written: list[Path] = []
    ca_key, ca_cert = _load_or_make_ca(out, written)
    if chair_names or not (out / "chair.pem").exists():
        names = ["localhost", "127.0.0.1", *chair_names]
        written += issue(out, "chair", "autochair-chair", names, server=True,
                         ca_key=ca_key, ca_cert=ca_cert)
    for name, role in laptops:
        written += issue(out, name, deploy.ROLE_CN[role], [name], server=False,
                         ca_key=ca_key, ca_cert=ca_cert)
        profile = out / f"{name}.json5"
        profile.write_text(deploy.json5(
            deploy.laptop_zenoh(str(out.resolve()), name, connect),
            f"Laptop {name} ({role}): `autochair monitor --zenoh-config {profile.name}`"))
        written.append(profile)
    return written


def _load_or_make_ca(out: Path, written: list[Path]) -> tuple[Any, Any]:
    from cryptography import x509
    from cryptography.hazmat.primitives import serialization

    key_path, cert_path = out / "ca-key.pem", out / "ca.pem"
    if key_path.exists() and cert_path.exists():
        key = serialization.load_pem_private_key(key_path.read_bytes(), None)
        return key, x509.load_pem_x509_certificate(cert_path.read_bytes())
    key = _new_key()
    name = _name("autochair CA", "")
    cert = _builder(name, name, key.public_key(), DAYS).add_extension(
        x509.BasicConstraints(ca=True, path_length=0), critical=True).add_extension(
        x509.KeyUsage(digital_signature=True, key_cert_sign=True, crl_sign=True,
                      content_commitment=False, key_encipherment=False, data_encipherment=False,
                      key_agreement=False, encipher_only=False, decipher_only=False),
        critical=True).sign(key, _sha256())
    written += _save(out, "ca", key, cert)
    return key, cert


def issue(out: Path, stem: str, cn: str, names: list[str], *, server: bool, ca_key: Any,
          ca_cert: Any) -> list[Path]:
    """Write OUT/<stem>.pem and OUT/<stem>-key.pem signed by the CA."""
    from cryptography import x509
    from cryptography.x509.oid import ExtendedKeyUsageOID

    key = _new_key()
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
    return _save(out, stem, key, cert)


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


def _save(out: Path, stem: str, key: Any, cert: Any) -> list[Path]:
    from cryptography.hazmat.primitives import serialization

    key_path, cert_path = out / f"{stem}-key.pem", out / f"{stem}.pem"
    key_path.touch(mode=0o600)
    key_path.write_bytes(key.private_bytes(serialization.Encoding.PEM,
                                           serialization.PrivateFormat.PKCS8,
                                           serialization.NoEncryption()))
    cert_path.write_bytes(cert.public_bytes(serialization.Encoding.PEM))
    return [cert_path, key_path]

