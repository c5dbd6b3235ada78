"""deploy/k8s: `kubectl kustomize` renders the base and the example overlay, kubernetes-validate accepts every
resource it has a schema for, and the rendered objects are the layout deploy/README.md describes."""

import subprocess
from typing import Any

import pytest
import yaml
from kombu.transport.redis import PRIORITY_STEPS

from tests.deploy.layout import DEMO_PROCESSES, DEPLOY, procfile_processes, tool
from workers.step_requests import StepPriority, step_queue_keys

KUSTOMIZATIONS = ["base", "overlays/example"]
DISPATCHER_LABEL = {"app.kubernetes.io/name": "mission-dispatch"}


def render(kustomization: str) -> list[dict[str, Any]]:
    kubectl = tool("kubectl", "apt-get install kubectl (its `kubectl kustomize` renders offline)")
    done = subprocess.run(
        [kubectl, "kustomize", str(DEPLOY / "k8s" / kustomization)],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 0, done.stderr
    return [document for document in yaml.safe_load_all(done.stdout) if document]


@pytest.fixture(scope="module")
def example() -> dict[tuple[str, str], dict[str, Any]]:
    return {(item["kind"], item["metadata"]["name"]): item for item in render("overlays/example")}


def pod_spec(resource: dict[str, Any]) -> dict[str, Any]:
    return resource["spec"]["template"]["spec"]


@pytest.mark.parametrize("kustomization", KUSTOMIZATIONS)
def test_renders_and_passes_schema_validation(kustomization: str, tmp_path):
    validator = tool(
        "kubernetes-validate",
        "pip install kubernetes-validate==1.37.0 (on the PATH, or into the venv running the tests)",
    )
    rendered = tmp_path / "rendered.yaml"
    rendered.write_text(yaml.safe_dump_all(render(kustomization)))
    done = subprocess.run(
        [validator, "--strict", "--quiet", str(rendered)], capture_output=True, text=True, timeout=300
    )
    assert done.returncode == 0, done.stdout + done.stderr
    # The only resource without a schema there is KEDA's ScaledObject (checked below by hand).
    unknown = [line for line in done.stdout.splitlines() if "Couldn't find schema" in line]
    assert all("kind ScaledObject with api version keda.sh/v1alpha1" in line for line in unknown), unknown


def test_every_server_process_is_a_deployment_running_its_role(example):
    for process in set(procfile_processes()) - DEMO_PROCESSES:
        deployment = example["Deployment", f"mission-dispatch-{process}"]
        (container,) = pod_spec(deployment)["containers"]
        assert container["args"] == [process]
        assert container["image"] == "registry.example.com/mission-dispatch:0.1.0"
    deployments = {name for kind, name in example if kind == "Deployment"}
    assert deployments == {f"mission-dispatch-{p}" for p in set(procfile_processes()) - DEMO_PROCESSES}


def test_every_container_has_requests_limits_and_runs_as_non_root(example):
    assert example["ServiceAccount", "mission-dispatch"]["automountServiceAccountToken"] is False
    for (kind, name), resource in example.items():
        if kind not in {"Deployment", "Job"}:
            continue
        spec = pod_spec(resource)
        assert spec["securityContext"]["runAsNonRoot"] is True, name
        assert spec["serviceAccountName"] == "mission-dispatch", name
        for container in spec.get("initContainers", []) + spec["containers"]:
            assert set(container["resources"]) == {"requests", "limits"}, name
            assert container["securityContext"]["allowPrivilegeEscalation"] is False, name


def test_beat_is_one_pod_never_two(example):
    beat = example["Deployment", "mission-dispatch-beat"]
    assert beat["spec"]["replicas"] == 1
    assert beat["spec"]["strategy"] == {"type": "Recreate"}
    targets = [
        resource["spec"].get("scaleTargetRef", {}).get("name")
        for (kind, _), resource in example.items()
        if kind in {"HorizontalPodAutoscaler", "ScaledObject"}
    ]
    assert "mission-dispatch-beat" not in targets


def test_workers_scale_on_the_length_of_the_steps_queue(example):
    scaled = example["ScaledObject", "mission-dispatch-worker"]
    assert scaled["spec"]["scaleTargetRef"] == {"name": "mission-dispatch-worker"}
    triggers = scaled["spec"]["triggers"]
    # kombu keeps a queue as a Redis list per priority: the asked-for steps' and the routine ones'..
    assert [trigger["metadata"]["listName"] for trigger in triggers] == [
        step_queue_keys()[0],
        step_queue_keys()[PRIORITY_STEPS.index(StepPriority.ROUTINE)],
    ]
    (config,) = [resource for (kind, _), resource in example.items() if kind == "ConfigMap"]
    redis_url = config["data"]["FLEET_REDIS_URL"]
    for trigger in triggers:
        assert trigger["type"] == "redis"
        assert trigger["metadata"]["address"].split(".")[0] == "redis-master"
        assert redis_url.startswith("redis://redis-master:6379/" + trigger["metadata"]["databaseIndex"])


def test_api_probes_service_and_ingress(example):
    (api,) = pod_spec(example["Deployment", "mission-dispatch-api"])["containers"]
    assert api["readinessProbe"]["httpGet"] == {"path": "/health", "port": "http"}
    assert api["livenessProbe"]["httpGet"] == {"path": "/health", "port": "http"}
    assert example["Service", "mission-dispatch-api"]["spec"]["ports"][0]["port"] == 5000
    paths = {
        path["path"]: path["backend"]["service"]["name"]
        for path in example["Ingress", "mission-dispatch"]["spec"]["rules"][0]["http"]["paths"]
    }
    assert paths == {
        "/": "mission-dispatch-api",
    }


def test_migrations_run_in_a_job_and_new_pods_wait_for_them(example):
    (job,) = pod_spec(example["Job", "mission-dispatch-migrate"])["containers"]
    assert job["args"] == ["migrate"]
    for (kind, name), resource in example.items():
        if kind == "Deployment":
            (init,) = pod_spec(resource)["initContainers"]
            assert init["args"] == ["manage.py", "migrate", "--check"], name


def test_disruption_budgets_for_the_replicated_processes(example):
    budgets = {name for kind, name in example if kind == "PodDisruptionBudget"}
    assert budgets == {f"mission-dispatch-{role}" for role in ("api", "bridge", "worker", "notify")}


def test_only_the_dispatchers_pods_reach_postgresql_and_redis(example):
    policies = {
        resource["spec"]["podSelector"]["matchLabels"]["app.kubernetes.io/name"]: resource["spec"]
        for (kind, _), resource in example.items()
        if kind == "NetworkPolicy"
    }
    assert set(policies) == {"postgresql", "redis"}
    for spec in policies.values():
        assert spec["policyTypes"] == ["Ingress"]
        (rule,) = spec["ingress"]
        assert rule["from"][0] == {"podSelector": {"matchLabels": DISPATCHER_LABEL}}
    # Every pod of ours carries the label the policies admit.
    for (kind, name), resource in example.items():
        if kind in {"Deployment", "Job"}:
            labels = resource["spec"]["template"]["metadata"]["labels"]
            assert labels.items() >= DISPATCHER_LABEL.items(), name
