//! The deployment files under `deploy/` (README, "Deploying: Kubernetes and Compose").
//!
//! `deploy`: every Kubernetes manifest under `deploy/kubernetes/` (all but `kustomization.yaml`,
//! which is kustomize's, not an API object) validates against the Kubernetes API's JSON schemas
//! of [`K8S_VERSIONS`] in strict mode (unknown fields rejected), with the PyPI package
//! `kubernetes-validate`; `deploy/compose.yaml` against the Compose specification's schema
//! (`compose-spec.json` as shipped by the PyPI package `check-jsonschema`). Both packages carry
//! their schemas, so this runs offline. The validators must also reject: copies with a misspelled
//! field (top level and nested) fail each of them. Without the packages the test prints one line
//! `SKIPPED (no manifest validators: pip install …): deploy` and returns, unless
//! `MANYHANDS_REQUIRE_DEPLOY_TOOLS=1` (set by `.ci/run`, which installs them), where it fails.
//! `MANYHANDS_DEPLOY_PYTHON` names the Python that has them (default `python3`).
//!
//! `deploy_consistency` (no tools needed): what no schema knows — the objects name each other
//! correctly, the shutdown budget fits the grace periods, tokens are long enough for the server,
//! the kustomization lists every manifest, every file opens with a header comment.

use std::collections::BTreeSet;
use std::io::Write;
use std::path::PathBuf;
use std::process::{Command, Stdio};

use yaml_rust2::{Yaml, YamlLoader};

/// The Kubernetes versions whose schemas the manifests must satisfy (kubernetes-validate ships
/// 1.25 and later).
const K8S_VERSIONS: &[&str] = &["1.30.0", "1.34.0"];
/// The packages, as `.ci/run` installs them.
const TOOLS: &str = "kubernetes-validate==1.37.0 check-jsonschema==0.39.0";
const REQUIRE_ENV: &str = "MANYHANDS_REQUIRE_DEPLOY_TOOLS";
const PYTHON_ENV: &str = "MANYHANDS_DEPLOY_PYTHON";

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn python() -> String {
    std::env::var(PYTHON_ENV)
        .ok()
        .filter(|p| !p.is_empty())
        .unwrap_or_else(|| "python3".into())
}

/// The installed versions of both validators, or why they cannot be run.
fn tools(py: &str) -> Result<String, String> {
    let out = Command::new(py)
        .args([
            "-c",
            "import kubernetes_validate, check_jsonschema, importlib.metadata as m; \
             print('kubernetes-validate', m.version('kubernetes-validate'), \
             '+ check-jsonschema', m.version('check-jsonschema'))",
        ])
        .output()
        .map_err(|e| format!("cannot run {py}: {e}"))?;
    if !out.status.success() {
        let err = String::from_utf8_lossy(&out.stderr);
        return Err(format!(
            "{py} lacks them: {}",
            err.lines().last().unwrap_or("no output")
        ));
    }
    Ok(String::from_utf8_lossy(&out.stdout).trim().to_string())
}

/// One validator run: whether it accepted everything, and what it said.
struct Run {
    ok: bool,
    text: String,
}

/// Runs `python -m MODULE ARGS` in the repository root, `stdin` fed to it when given. A run is
/// `ok` when it exits 0 and prints no WARN/ERROR/FATAL line (kubernetes-validate only warns,
/// exit 0, about a kind it has no schema for).
fn run(py: &str, module: &str, args: &[&str], stdin: Option<&str>) -> Run {
    let mut child = Command::new(py)
        .arg("-m")
        .arg(module)
        .args(args)
        .current_dir(root())
        .stdin(if stdin.is_some() {
            Stdio::piped()
        } else {
            Stdio::null()
        })
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap_or_else(|e| panic!("run {py} -m {module}: {e}"));
    if let Some(text) = stdin {
        child
            .stdin
            .take()
            .unwrap()
            .write_all(text.as_bytes())
            .unwrap();
    }
    let out = child.wait_with_output().unwrap();
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    let complaint = text
        .lines()
        .any(|l| l.starts_with("WARN") || l.starts_with("ERROR") || l.starts_with("FATAL"));
    Run {
        ok: out.status.success() && !complaint,
        text,
    }
}

fn kubernetes_validate(py: &str, files: &[&str], stdin: Option<&str>) -> Run {
    let mut args = vec!["--strict"];
    for v in K8S_VERSIONS {
        args.extend(["-k", *v]);
    }
    args.extend(files);
    run(py, "kubernetes_validate", &args, stdin)
}

fn compose_validate(py: &str, file: &str, stdin: Option<&str>) -> Run {
    let args = [
        "--builtin-schema",
        "vendor.compose-spec",
        "--force-filetype",
        "yaml",
        file,
    ];
    run(py, "check_jsonschema", &args, stdin)
}

/// The manifests under deploy/kubernetes/ (repository-relative, sorted), kustomization.yaml
/// apart.
fn manifests() -> Vec<String> {
    let mut files: Vec<String> = std::fs::read_dir(root().join("deploy/kubernetes"))
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".yaml") && n != "kustomization.yaml")
        .map(|n| format!("deploy/kubernetes/{n}"))
        .collect();
    files.sort();
    files
}

fn read(rel: &str) -> String {
    std::fs::read_to_string(root().join(rel)).unwrap_or_else(|e| panic!("read {rel}: {e}"))
}

/// `text` with the first `from` replaced by `to`; panics when `from` is not there.
fn broken(text: &str, from: &str, to: &str) -> String {
    assert!(text.contains(from), "{from:?} not found to break");
    text.replacen(from, to, 1)
}

#[test]
fn deploy() {
    let py = python();
    let versions = match tools(&py) {
        Ok(v) => v,
        Err(why) => {
            let required = std::env::var(REQUIRE_ENV).is_ok_and(|v| v == "1");
            let skip = format!("no manifest validators: pip install {TOOLS}");
            let line = manyhands::skips::line(&skip);
            assert!(!required, "{REQUIRE_ENV}=1 but {why}: {line}");
            manyhands::skips::report(&skip);
            return;
        }
    };

    // Every manifest, against every version: one "passed" line each, no complaint.
    let files = manifests();
    assert!(files.len() >= 6, "manifests: {files:?}");
    let refs: Vec<&str> = files.iter().map(String::as_str).collect();
    let k = kubernetes_validate(&py, &refs, None);
    assert!(
        k.ok,
        "kubernetes-validate rejected the manifests:\n{}",
        k.text
    );
    for f in &files {
        for v in K8S_VERSIONS {
            let minor = v.rsplit_once('.').unwrap().0;
            let passed = format!("INFO {f} passed for resource ");
            let version = format!(" against version {minor}");
            assert!(
                k.text
                    .lines()
                    .any(|l| l.starts_with(&passed) && l.ends_with(&version)),
                "{f} not validated for Kubernetes {minor}:\n{}",
                k.text
            );
        }
    }
    let c = compose_validate(&py, "deploy/compose.yaml", None);
    assert!(
        c.ok && c.text.contains("ok -- validation done"),
        "check-jsonschema rejected deploy/compose.yaml:\n{}",
        c.text
    );

    // The validators reject broken copies: strict mode finds unknown fields at any depth.
    let deployment = read("deploy/kubernetes/deployment.yaml");
    let compose = read("deploy/compose.yaml");
    let bad_k8s = [
        (
            "spec.replicass",
            broken(&deployment, "\n  replicas:", "\n  replicass:"),
        ),
        (
            "containers[0].readinesProbe",
            broken(&deployment, "readinessProbe:", "readinesProbe:"),
        ),
    ];
    for (what, text) in &bad_k8s {
        let r = kubernetes_validate(&py, &["-"], Some(text));
        let field = what.rsplit('.').next().unwrap();
        assert!(
            !r.ok && r.text.contains(&format!("'{field}' was unexpected")),
            "kubernetes-validate accepted a Deployment with {what}:\n{}",
            r.text
        );
    }
    let bad_compose = [
        (
            "top-level servicess",
            format!("{compose}\nservicess: {{}}\n"),
            "servicess",
        ),
        (
            "services.manyhands-a.stop_grace_periods",
            broken(&compose, "stop_grace_period:", "stop_grace_periods:"),
            "stop_grace_periods",
        ),
    ];
    for (what, text, field) in &bad_compose {
        let r = compose_validate(&py, "-", Some(text));
        assert!(
            !r.ok && r.text.contains(&format!("'{field}'")),
            "check-jsonschema accepted compose.yaml with {what}:\n{}",
            r.text
        );
    }

    let minors: Vec<&str> = K8S_VERSIONS
        .iter()
        .map(|v| v.rsplit_once('.').unwrap().0)
        .collect();
    eprintln!("{}", k.text.trim_end());
    eprintln!("deploy/compose.yaml: {}", c.text.trim());
    eprintln!(
        "deploy: {} manifests valid for Kubernetes {} (strict) and deploy/compose.yaml for the \
         Compose spec, with {versions}; {} broken copies rejected",
        files.len(),
        minors.join(" and "),
        bad_k8s.len() + bad_compose.len()
    );
}

// ---- consistency (no tools) ----

fn load(rel: &str) -> Yaml {
    let mut docs = YamlLoader::load_from_str(&read(rel)).unwrap_or_else(|e| panic!("{rel}: {e}"));
    assert_eq!(docs.len(), 1, "{rel}: one document");
    docs.remove(0)
}

fn s<'a>(y: &'a Yaml, what: &str) -> &'a str {
    y.as_str()
        .unwrap_or_else(|| panic!("{what}: a string, got {y:?}"))
}

fn num(y: &Yaml, what: &str) -> f64 {
    y.as_i64()
        .map(|i| i as f64)
        .or_else(|| y.as_str().and_then(|t| t.parse().ok()))
        .unwrap_or_else(|| panic!("{what}: a number, got {y:?}"))
}

/// A Compose duration ("40s", "1m30s", "500ms") in seconds.
fn duration(text: &str) -> f64 {
    let (mut total, mut digits) = (0.0, String::new());
    let mut chars = text.chars().peekable();
    while let Some(ch) = chars.next() {
        if ch.is_ascii_digit() || ch == '.' {
            digits.push(ch);
            continue;
        }
        let unit = match (ch, chars.peek()) {
            ('m', Some('s')) => {
                chars.next();
                0.001
            }
            ('h', _) => 3600.0,
            ('m', _) => 60.0,
            ('s', _) => 1.0,
            _ => panic!("duration {text:?}"),
        };
        total += digits.parse::<f64>().unwrap() * unit;
        digits.clear();
    }
    assert!(digits.is_empty(), "duration {text:?} without a unit");
    total
}

/// Whether every label of `selector` is on `labels`.
fn selects(selector: &Yaml, labels: &Yaml) -> bool {
    let sel = selector.as_hash().expect("a selector");
    !sel.is_empty() && sel.iter().all(|(k, v)| labels[s(k, "label")] == *v)
}

#[test]
fn deploy_consistency() {
    let dir = root().join("deploy/kubernetes");

    // Every file opens with a header comment; the kustomization lists every manifest.
    let mut all: Vec<String> = manifests();
    all.extend([
        "deploy/kubernetes/kustomization.yaml".into(),
        "deploy/compose.yaml".into(),
        "deploy/nginx.conf".into(),
    ]);
    for f in &all {
        assert!(read(f).starts_with("# "), "{f}: no header comment");
    }
    let kustomization = load("deploy/kubernetes/kustomization.yaml");
    let listed: BTreeSet<String> = kustomization["resources"]
        .as_vec()
        .expect("kustomization resources")
        .iter()
        .map(|r| format!("deploy/kubernetes/{}", s(r, "resource")))
        .collect();
    assert_eq!(
        listed,
        manifests().into_iter().collect::<BTreeSet<_>>(),
        "kustomization.yaml's resources vs the files in {}",
        dir.display()
    );

    let config = load("deploy/kubernetes/configmap.yaml");
    let secret = load("deploy/kubernetes/secret.yaml");
    let deployment = load("deploy/kubernetes/deployment.yaml");
    let service = load("deploy/kubernetes/service.yaml");
    let hpa = load("deploy/kubernetes/hpa.yaml");
    let pdb = load("deploy/kubernetes/pdb.yaml");
    let name = |y: &Yaml| s(&y["metadata"]["name"], "metadata.name").to_string();
    let data = &config["data"];
    let secrets = &secret["stringData"];

    // The pod: the names it refers to exist, with the keys it reads.
    let pod = &deployment["spec"]["template"];
    let labels = &pod["metadata"]["labels"];
    let spec = &pod["spec"];
    let containers = spec["containers"].as_vec().expect("containers");
    assert_eq!(containers.len(), 1);
    let c = &containers[0];
    assert_eq!(
        s(&c["envFrom"][0]["configMapRef"]["name"], "envFrom"),
        name(&config)
    );
    let env = c["env"].as_vec().expect("env");
    let env_of = |n: &str| {
        env.iter()
            .find(|e| e["name"].as_str() == Some(n))
            .unwrap_or_else(|| panic!("{n} not in the container's env"))
    };
    for key in ["MANYHANDS_TOKEN", "MANYHANDS_STORE"] {
        let r = &env_of(key)["valueFrom"]["secretKeyRef"];
        assert_eq!(s(&r["name"], "secretKeyRef.name"), name(&secret));
        assert!(
            !secrets[s(&r["key"], "secretKeyRef.key")].is_badvalue(),
            "{key} not in the Secret"
        );
    }
    assert_eq!(
        s(
            &env_of("MANYHANDS_REPLICA_ID")["valueFrom"]["fieldRef"]["fieldPath"],
            "fieldPath"
        ),
        "metadata.name"
    );
    assert!(
        s(&secrets["MANYHANDS_TOKEN"], "token").len() >= 16,
        "the Secret's example token is shorter than the server accepts"
    );
    assert!(s(&secrets["MANYHANDS_STORE"], "store").starts_with("postgres://"));

    // Probes, port and the listener agree.
    assert_eq!(
        s(&c["readinessProbe"]["httpGet"]["path"], "readiness"),
        "/readyz"
    );
    assert_eq!(
        s(&c["livenessProbe"]["httpGet"]["path"], "liveness"),
        "/healthz"
    );
    let port = &c["ports"][0];
    assert_eq!(port["containerPort"].as_i64(), Some(8080));
    assert_eq!(s(&data["MANYHANDS_BIND"], "bind"), "0.0.0.0:8080");
    let target = s(&service["spec"]["ports"][0]["targetPort"], "targetPort");
    assert_eq!(target, s(&port["name"], "port name"));
    for p in ["readinessProbe", "livenessProbe", "startupProbe"] {
        assert_eq!(s(&c[p]["httpGet"]["port"], p), target);
    }

    // Shutdown: the preStop sleep, then the server's drain and grace, within the pod's grace.
    let pre_stop = c["lifecycle"]["preStop"]["exec"]["command"]
        .as_vec()
        .expect("preStop command");
    assert_eq!(s(&pre_stop[0], "preStop"), "sleep");
    let sleep = num(&pre_stop[1], "preStop sleep");
    let drain = num(&data["MANYHANDS_DRAIN"], "drain");
    let grace = num(&data["MANYHANDS_SHUTDOWN_GRACE"], "grace");
    let pod_grace = num(
        &spec["terminationGracePeriodSeconds"],
        "terminationGracePeriodSeconds",
    );
    assert!(
        drain <= grace && sleep + drain + grace < pod_grace,
        "preStop {sleep} + drain {drain} + grace {grace} must stay below {pod_grace}"
    );

    // Security: the image's user, nothing writable but the volumes.
    let sc = &c["securityContext"];
    assert_eq!(sc["runAsNonRoot"].as_bool(), Some(true));
    assert_eq!(sc["runAsUser"].as_i64(), Some(10001));
    assert_eq!(sc["readOnlyRootFilesystem"].as_bool(), Some(true));
    assert_eq!(sc["allowPrivilegeEscalation"].as_bool(), Some(false));
    assert_eq!(s(&sc["capabilities"]["drop"][0], "drop"), "ALL");
    let mounts = c["volumeMounts"].as_vec().expect("volumeMounts");
    assert!(mounts
        .iter()
        .any(|m| m["mountPath"].as_str() == Some(s(&data["MANYHANDS_DATA_DIR"], "data dir"))));

    // Selectors pick the pods; the autoscaler scales this Deployment.
    assert!(selects(
        &deployment["spec"]["selector"]["matchLabels"],
        labels
    ));
    assert!(selects(&service["spec"]["selector"], labels));
    assert!(selects(&pdb["spec"]["selector"]["matchLabels"], labels));
    let scale = &hpa["spec"]["scaleTargetRef"];
    assert_eq!(s(&scale["kind"], "kind"), "Deployment");
    assert_eq!(s(&scale["name"], "name"), name(&deployment));
    let min = hpa["spec"]["minReplicas"].as_i64().unwrap();
    assert!(pdb["spec"]["minAvailable"].as_i64().unwrap() < min);

    // Compose: two replicas on one PostgreSQL, each stopping within its grace period.
    let compose = load("deploy/compose.yaml");
    let services = &compose["services"];
    assert!(!services["postgres"].is_badvalue());
    let mut ids = BTreeSet::new();
    for r in ["manyhands-a", "manyhands-b"] {
        let svc = &services[r];
        let env = &svc["environment"];
        let store = s(&env["MANYHANDS_STORE"], "MANYHANDS_STORE");
        assert!(store.starts_with("postgres://") && store.contains("@postgres:5432/"));
        assert!(ids.insert(s(&env["MANYHANDS_REPLICA_ID"], "replica id").to_string()));
        assert!(
            s(&env["MANYHANDS_TOKEN"], "token").len() >= 16,
            "{r}: token too short"
        );
        let budget =
            num(&env["MANYHANDS_DRAIN"], "drain") + num(&env["MANYHANDS_SHUTDOWN_GRACE"], "grace");
        let stop = duration(s(&svc["stop_grace_period"], "stop_grace_period"));
        assert!(
            stop > budget,
            "{r}: stop_grace_period {stop} s vs {budget} s"
        );
        assert_eq!(
            s(&svc["depends_on"]["postgres"]["condition"], "depends_on"),
            "service_healthy"
        );
        let check = svc["healthcheck"]["test"].as_vec().expect("healthcheck");
        assert!(check
            .iter()
            .any(|t| t.as_str().is_some_and(|t| t.ends_with("/readyz"))));
        let context = s(&svc["build"]["context"], "build context");
        let dockerfile = s(&svc["build"]["dockerfile"], "dockerfile");
        assert!(root()
            .join("deploy")
            .join(context)
            .join(dockerfile)
            .is_file());
    }

    // The Dockerfile's example token is one the server accepts.
    let dockerfile = read("Dockerfile");
    let token = dockerfile
        .split("MANYHANDS_TOKEN=")
        .nth(1)
        .and_then(|t| t.split_whitespace().next())
        .expect("the Dockerfile's example token");
    assert!(token.len() >= 16, "Dockerfile example token {token:?}");
}
