//! examples/kubernetes/render-job.yaml has what the Job API requires, and its shard
//! count, index variable and merge step agree with each other. No cluster runs here.

use serde_yaml::Value;

fn docs() -> Vec<Value> {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/examples/kubernetes/render-job.yaml");
    let text = std::fs::read_to_string(path).expect("read the manifest");
    serde_yaml::Deserializer::from_str(&text).map(|d| serde::Deserialize::deserialize(d).expect("YAML")).collect()
}

fn get<'a>(v: &'a Value, path: &str) -> &'a Value {
    let mut at = v;
    for key in path.split('.') {
        at = match key.parse::<usize>() {
            Ok(i) => at.get(i),
            Err(_) => at.get(key),
        }
        .unwrap_or_else(|| panic!("missing {path} (at {key})"));
    }
    at
}

fn str_of<'a>(v: &'a Value, path: &str) -> &'a str {
    get(v, path).as_str().unwrap_or_else(|| panic!("{path} is not a string"))
}

fn int_of(v: &Value, path: &str) -> u64 {
    get(v, path).as_u64().unwrap_or_else(|| panic!("{path} is not a number"))
}

/// The checks every Job (batch/v1) must pass: name, a pod template with a restart
/// policy a Job accepts and named containers with images, and mounts of declared
/// volumes (claims of a PersistentVolumeClaim in the file).
fn check_job(job: &Value, claims: &[String]) {
    assert_eq!(str_of(job, "apiVersion"), "batch/v1");
    let name = str_of(job, "metadata.name");
    assert!(
        !name.is_empty()
            && name.len() <= 63
            && name.chars().all(|c| c.is_ascii_lowercase() || c.is_ascii_digit() || c == '-')
    );
    let pod = get(job, "spec.template.spec");
    assert!(
        ["Never", "OnFailure"].contains(&str_of(pod, "restartPolicy")),
        "{name}: a Job's pods restart Never or OnFailure"
    );
    let volumes: Vec<&str> =
        get(pod, "volumes").as_sequence().expect("volumes").iter().map(|v| str_of(v, "name")).collect();
    for v in get(pod, "volumes").as_sequence().expect("volumes") {
        let claim = str_of(v, "persistentVolumeClaim.claimName");
        assert!(claims.iter().any(|c| c == claim), "{name}: claim {claim} is declared in the file");
    }
    let containers = get(pod, "containers").as_sequence().expect("containers");
    assert!(!containers.is_empty());
    for c in containers {
        assert!(!str_of(c, "name").is_empty() && !str_of(c, "image").is_empty());
        for m in get(c, "volumeMounts").as_sequence().expect("mounts") {
            assert!(volumes.contains(&str_of(m, "name")), "{name}: mount of an undeclared volume");
            assert!(str_of(m, "mountPath").starts_with('/'));
        }
    }
}

fn script(job: &Value) -> String {
    let c = get(job, "spec.template.spec.containers.0");
    let mut words: Vec<String> = Vec::new();
    for key in ["command", "args"] {
        if let Some(list) = c.get(key).and_then(Value::as_sequence) {
            words.extend(list.iter().map(|w| w.as_str().expect("a string").to_string()));
        }
    }
    words.join(" ")
}

#[test]
fn the_indexed_job_and_the_merge_job_are_complete_and_agree() {
    let docs = docs();
    let claims: Vec<String> = docs
        .iter()
        .filter(|d| str_of(d, "kind") == "PersistentVolumeClaim")
        .map(|d| str_of(d, "metadata.name").to_string())
        .collect();
    assert_eq!(claims.len(), 1, "one shared volume");
    let jobs: Vec<&Value> = docs.iter().filter(|d| str_of(d, "kind") == "Job").collect();
    assert_eq!(jobs.len(), 2, "a render Job and a merge Job");
    for j in &jobs {
        check_job(j, &claims);
    }
    let render = jobs.iter().find(|j| get(j, "spec").get("completionMode").is_some()).expect("the Indexed Job");
    assert_eq!(str_of(render, "spec.completionMode"), "Indexed");
    let n = int_of(render, "spec.completions");
    assert!(n >= 1 && int_of(render, "spec.parallelism") <= n);
    let cmd = script(render);
    assert!(cmd.contains(&format!("--shard auto/{n}")), "the shard count is the completion count: {cmd}");
    assert!(cmd.contains("JOB_COMPLETION_INDEX") && cmd.contains("--resume"), "{cmd}");
    let merge = jobs.iter().find(|j| script(j).contains("arbor merge")).expect("the merge Job");
    assert!(get(merge, "spec").get("completionMode").is_none());
    // The merge reads the parts where the render writes them.
    assert!(script(merge).contains("/work/parts/part-*.exr") && cmd.contains("/work/parts/part-"));
}
