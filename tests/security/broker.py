"""A private Mosquitto running the shipped production configuration (deploy/mosquitto/), with certificates
made for the test by the `openssl` CLI and logins made by the shipped `add-robot` script and
`mosquitto_passwd -b`. Only paths and ports of the copy are changed (and `require_certificate true` added
where a test asks for deploy/README.md's client-certificate variant): listeners, authentication and the ACL
are the shipped ones."""

from __future__ import annotations

import os
import pwd
import shutil
import subprocess
from dataclasses import dataclass, field
from pathlib import Path

from simulator.config import Credentials, parse_credentials
from tests.faults.stack import ROOT, Proc, free_port, port_open, wait_until

SHIPPED = ROOT / "deploy" / "mosquitto"
SHIPPED_DIRECTORY = "/etc/mosquitto"
SHIPPED_PORT = 8883
HOST = "localhost"  # the name in the broker's certificate (and nothing else: not 127.0.0.1)
DISPATCHER = "dispatcher"  # the ACL's dispatcher user


@dataclass(frozen=True)
class Certificates:
    ca: Path
    server_cert: Path
    server_key: Path
    client_cert: Path  # the dispatcher's, for brokers that require client certificates
    client_key: Path
    other_ca: Path  # a CA that signed nothing of the broker's


def openssl(directory: Path, *args: str) -> None:
    subprocess.run(["openssl", *args], cwd=directory, check=True, capture_output=True)


def make_certificates(directory: Path) -> Certificates:
    """A CA, the broker's certificate for `localhost` and the dispatcher's client certificate signed by it,
    and a stranger CA."""
    directory.mkdir(parents=True, exist_ok=True)
    new_key = ["-newkey", "ec", "-pkeyopt", "ec_paramgen_curve:P-256", "-nodes"]
    for ca in ("ca", "other-ca"):
        subject = f"/CN=Mission Dispatch test {ca}"
        openssl(directory, "req", "-x509", *new_key, "-days", "2", "-keyout", f"{ca}.key",
                "-out", f"{ca}.crt", "-subj", subject)  # fmt: skip
    for name, subject, extension in (
        ("server", HOST, f"subjectAltName=DNS:{HOST}"),
        ("client", DISPATCHER, "extendedKeyUsage=clientAuth"),
    ):
        (directory / f"{name}.ext").write_text(f"{extension}\n")
        openssl(directory, "req", *new_key, "-keyout", f"{name}.key", "-out", f"{name}.csr",
                "-subj", f"/CN={subject}")  # fmt: skip
        openssl(directory, "x509", "-req", "-in", f"{name}.csr", "-CA", "ca.crt", "-CAkey", "ca.key",
                "-CAcreateserial", "-out", f"{name}.crt", "-days", "2",
                "-extfile", f"{name}.ext")  # fmt: skip
    return Certificates(
        ca=directory / "ca.crt",
        server_cert=directory / "server.crt",
        server_key=directory / "server.key",
        client_cert=directory / "client.crt",
        client_key=directory / "client.key",
        other_ca=directory / "other-ca.crt",
    )


@dataclass
class SecuredBroker:
    """deploy/mosquitto/ copied to `directory` (its /etc/mosquitto), on a free port of 127.0.0.1."""

    directory: Path
    certificates: Certificates
    port: int = field(default_factory=free_port)
    dispatcher_password: str = "dispatcher-secret"
    require_certificate: bool = False  # the listener option deploy/README.md tells how to add
    robots: dict[str, Credentials] = field(default_factory=dict)  # serial number -> its login
    process: Proc | None = None

    @property
    def etc(self) -> Path:
        return self.directory / "etc"

    @property
    def password_file(self) -> Path:
        return self.etc / "passwd"

    @property
    def credentials_file(self) -> Path:
        return self.directory / "robot-credentials"

    def install(self) -> None:
        shutil.copytree(SHIPPED, self.etc)
        certs = self.etc / "certs"
        certs.mkdir()
        for source, name in (
            (self.certificates.ca, "ca.crt"),
            (self.certificates.server_cert, "server.crt"),
            (self.certificates.server_key, "server.key"),
        ):
            shutil.copy(source, certs / name)
        config = self.etc / "mosquitto.conf"
        text = config.read_text()
        listener = f"listener {SHIPPED_PORT}\n"
        assert text.count(listener) == 1 and SHIPPED_DIRECTORY in text
        ours = f"listener {self.port} 127.0.0.1\n"
        if self.require_certificate:
            ours += "require_certificate true\n"
        text = text.replace(listener, ours)
        config.write_text(text.replace(SHIPPED_DIRECTORY, str(self.etc)))
        subprocess.run(
            ["mosquitto_passwd", "-c", "-b", self.password_file, DISPATCHER, self.dispatcher_password],
            check=True,
            capture_output=True,
        )

    def add_robot(self, serial_number: str) -> Credentials:
        """The robot's login, made by the shipped script, which also adds it to the simulator's credentials
        file. Make every login before `start`."""
        subprocess.run(
            [SHIPPED / "add-robot", self.password_file, serial_number, self.credentials_file],
            check=True,
            capture_output=True,
        )
        self.robots[serial_number] = parse_credentials(self.credentials_file.read_text())[serial_number]
        return self.robots[serial_number]

    def serial_number(self, base: str) -> str:
        """The serial number (and username) of the robot whose login `add_robot` made from `base`-..."""
        (serial_number,) = [serial for serial in self.robots if serial.startswith(f"{base}-")]
        return serial_number

    def start(self) -> None:
        """Start with the logins made so far (Mosquitto reads its password file at start). Started as root,
        Mosquitto runs as the `mosquitto` user, which must be able to read its files."""
        if os.geteuid() == 0:
            user = pwd.getpwnam("mosquitto")
            os.chmod(self.directory, 0o755)
            for path in [self.etc, *self.etc.rglob("*")]:
                os.chown(path, user.pw_uid, user.pw_gid)
        argv = ["mosquitto", "-c", str(self.etc / "mosquitto.conf")]
        self.process = Proc("secured-broker", argv, dict(os.environ), self.directory / "broker.log")
        self.process.start()
        wait_until(lambda: port_open(self.port), f"the secured Mosquitto on port {self.port}", timeout=30)

    def stop(self) -> None:
        if self.process is not None:
            self.process.stop()
