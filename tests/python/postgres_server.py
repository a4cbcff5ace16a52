"""A PostgreSQL server of a test module's own (Debian's postgresql: initdb, pg_ctl), as tests/support/postgres_server.hpp
starts one for the C++ tests: its files in a folder of the build tree, owned by the `postgres` user when the tests run
as root (PostgreSQL refuses to run as root), listening on 127.0.0.1 on a port the kernel found free, with trust for
the role feedid_admin; stopped by its process id."""

import os
import pathlib
import pwd
import shutil
import signal
import socket
import subprocess
import time
from typing import Optional


def _binaries() -> Optional[pathlib.Path]:
    given = os.environ.get("FEEDID_TEST_POSTGRES_BIN")
    candidates = [pathlib.Path(given)] if given else []
    root = pathlib.Path("/usr/lib/postgresql")
    if root.is_dir():
        candidates += sorted((p / "bin" for p in root.iterdir()), reverse=True)  # the newest first
    for bin_dir in candidates:
        if (bin_dir / "initdb").exists() and (bin_dir / "pg_ctl").exists():
            return bin_dir
    return None


def _free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class PostgresServer:
    """start() returns None when a server runs, else why there is none; location(db) is its postgresql:// URL."""

    def __init__(self, folder: pathlib.Path):
        self.folder = folder
        self.port = 0
        self.pid = 0
        self._bin = _binaries()
        self._user = None

    def _run(self, *arguments: str) -> subprocess.CompletedProcess:
        command = [str(a) for a in arguments]
        if self._user is not None:
            command = ["runuser", "-u", self._user.pw_name, "--", *command]
        return subprocess.run(command, capture_output=True, text=True, timeout=120)

    def start(self) -> Optional[str]:
        if self._bin is None:
            return "PostgreSQL's server binaries (initdb, pg_ctl) are not installed (Debian: postgresql)"
        if os.geteuid() == 0:
            try:
                self._user = pwd.getpwnam("postgres")
            except KeyError:
                return "running as root and there is no 'postgres' user to run the server as"
        shutil.rmtree(self.folder, ignore_errors=True)
        self.folder.mkdir(parents=True)
        if self._user is not None:
            os.chown(self.folder, self._user.pw_uid, self._user.pw_gid)
        os.chmod(self.folder, 0o700)
        cluster = self.folder / "cluster"
        made = self._run(self._bin / "initdb", "-D", cluster, "-U", "feedid_admin", "-A", "trust", "--no-sync",
                         "-E", "UTF8", "--no-locale")
        if made.returncode != 0:
            return f"initdb failed in {cluster}: {made.stderr.strip()}"
        settings = ("\nlisten_addresses = '127.0.0.1'\nunix_socket_directories = ''\nfsync = off\n"
                    "full_page_writes = off\n")
        self._run("sh", "-c", f"printf '%s' \"{settings}\" >> '{cluster}/postgresql.conf'")
        for _ in range(5):
            self.port = _free_port()
            started = self._run(self._bin / "pg_ctl", "-D", cluster, "-l", self.folder / "server.log", "-w",
                                "-t", "60", "-o", f"-p {self.port}", "start")
            if started.returncode == 0:
                self.pid = int((cluster / "postmaster.pid").read_text().split("\n", 1)[0])
                return None
        return f"the test server did not start (see {self.folder / 'server.log'})"

    def location(self, database: str) -> str:
        return f"postgresql://feedid_admin@127.0.0.1:{self.port}/{database}"

    def create_database(self, name: str) -> str:
        made = self._run(self._bin / "createdb", "-h", "127.0.0.1", "-p", str(self.port), "-U", "feedid_admin", name)
        assert made.returncode == 0, made.stderr
        return self.location(name)

    def stop(self) -> None:
        """SIGINT (PostgreSQL's fast shutdown) to the server's process, then waits for it to be gone."""
        if not self.pid:
            return
        try:
            os.kill(self.pid, signal.SIGINT)
            for _ in range(600):
                os.kill(self.pid, 0)
                time.sleep(0.05)
        except ProcessLookupError:
            pass
        self.pid = 0
        shutil.rmtree(self.folder, ignore_errors=True)
