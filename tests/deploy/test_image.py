"""The image's build context: every package the processes import is in it (a new app left out of the
image would pass every other test and fail only in a container), and what must stay out is out."""

import fnmatch
import tomllib

from django.conf import settings

from tests.deploy.layout import ROOT, procfile_processes

IGNORED = [
    line.strip()
    for line in (ROOT / ".dockerignore").read_text().splitlines()
    if line.strip() and not line.startswith("#")
]


def ignored(path: str) -> bool:
    """Whether .dockerignore leaves `path` (relative to the repository) out of the build context."""
    parts = path.split("/")
    prefixes = ["/".join(parts[: index + 1]) for index in range(len(parts))]
    return any(fnmatch.fnmatch(prefix, pattern) for prefix in prefixes for pattern in IGNORED)


def project_packages() -> set[str]:
    """The repository's top-level Python packages, but the tests' and the benchmark's."""
    return {
        path.parent.name
        for path in ROOT.glob("*/__init__.py")
        if path.parent.name not in ("tests", "bench")
    }


def test_every_package_is_installed_by_pyproject():
    config = tomllib.loads((ROOT / "pyproject.toml").read_text())
    patterns = config["tool"]["setuptools"]["packages"]["find"]["include"]
    included = {pattern.rstrip("*") for pattern in patterns}
    assert project_packages() <= included


def test_every_local_django_app_and_process_module_is_in_the_image():
    local_apps = [app for app in settings.INSTALLED_APPS if (ROOT / app.split(".")[0]).is_dir()]
    assert "fleet" not in local_apps  # not an app, but the settings' package: checked with the rest below
    for package in [*local_apps, *project_packages()]:
        assert not ignored(package.split(".")[0]), package
    for path in ("manage.py", "deploy/Procfile", "deploy/ensure_database.py", "deploy/container/entrypoint"):
        assert (ROOT / path).exists() and not ignored(path), path
    assert procfile_processes()


def test_local_files_tests_and_secrets_stay_out():
    local = (".git", ".venv", ".fleet", "tests", "fleet/__pycache__")
    for path in (*local, "deploy/compose/secrets/secret-key"):
        assert ignored(path), path
