#!/usr/bin/env bash
# The container check (not part of the test suite): build deploy/Dockerfile with podman on a
# base image made from Debian packages, start deploy/compose.yaml (api + worker) with
# podman-compose, submit a small study with the token, wait for it, fetch its plot, check
# that a request without the token is refused, then tear the stack down.
#
#   apt-get install -y podman runc mmdebstrap                    (once, as root)
#   python3 -m venv /opt/pc && /opt/pc/bin/pip install podman-compose
#   PODMAN_COMPOSE=/opt/pc/bin/podman-compose bash deploy/podman_check.sh
# podman-compose must be 1.1 or newer: Debian 12's 1.0.3 adds a bridge network to services
# with network_mode: host, which podman refuses ("cannot set multiple networks").
#
# Environment: PODMAN_CHECK_DIR (work directory, default /tmp/demscale-podman-check; the
# base image's rootfs.tar is kept there), DEMSCALE_PORT (default 18011), KEEP=1 (leave the
# stack running). Works without an image registry and without container networking: the
# containers use the host's network (compose.podman.yaml) and the API listens on 127.0.0.1.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
WORK=${PODMAN_CHECK_DIR:-/tmp/demscale-podman-check}
PORT=${DEMSCALE_PORT:-18011}
BASE=localhost/demscale-base:bookworm
mkdir -p "$WORK"
PODMAN_COMPOSE=${PODMAN_COMPOSE:-podman-compose}
for tool in podman runc mmdebstrap "$PODMAN_COMPOSE"; do
  command -v "$tool" >/dev/null || { echo "missing $tool (see the head of $0)" >&2; exit 2; }
done
# the runtime that works here, and no default ulimits (setting them fails in this sandbox)
cat > "$WORK/containers.conf" <<CONF
[containers]
default_ulimits = []
[engine]
runtime = "runc"
CONF
export CONTAINERS_CONF="$WORK/containers.conf"
t0=$(date +%s)
stamp() { echo "[$(( $(date +%s) - t0 )) s] $*"; }

if ! podman image exists "$BASE"; then
  stamp "making the base image $BASE from Debian packages (mmdebstrap)"
  [ -f "$WORK/rootfs.tar" ] || mmdebstrap --variant=minbase --include=python3,python3-venv \
    bookworm "$WORK/rootfs.tar"
  podman import "$WORK/rootfs.tar" "$BASE"
fi

stamp "building localhost/demscale:latest on $BASE"
# pip inside the build reaches PyPI through this machine's TLS-inspecting proxy: it needs the
# host's CA bundle (a build secret, not a layer of the image)
CA=${CA_BUNDLE:-/etc/ssl/certs/ca-certificates.crt}
podman build --network=host --build-arg "BASE=$BASE" --secret "id=ca,src=$CA" \
  -f deploy/Dockerfile -t localhost/demscale:latest . > "$WORK/build.log" 2>&1 \
  || { tail -n 30 "$WORK/build.log"; exit 1; }
tail -n 2 "$WORK/build.log"
stamp "image: $(podman image inspect localhost/demscale:latest --format '{{.Size}}') bytes"

export DEMSCALE_API_TOKEN=${DEMSCALE_API_TOKEN:-$(python3 -c 'import secrets; print(secrets.token_urlsafe(32))')}
export DEMSCALE_PORT=$PORT
COMPOSE=("$PODMAN_COMPOSE" -p demscale-check -f deploy/compose.yaml -f deploy/compose.podman.yaml)
down() {
  if [ "${KEEP:-0}" != 1 ]; then
    "${COMPOSE[@]}" down -v >/dev/null 2>&1 || true
  fi
}
trap down EXIT
stamp "starting the compose stack (api + worker)"
"${COMPOSE[@]}" up -d --no-build > "$WORK/compose.log" 2>&1 \
  || { tail -n 20 "$WORK/compose.log"; exit 1; }

stamp "submitting a study, waiting for it, fetching its plot"
python3 - "$PORT" "$DEMSCALE_API_TOKEN" "$WORK" <<'PY'
import json, sys, time, urllib.error, urllib.request

port, token, work = sys.argv[1], sys.argv[2], sys.argv[3]
base = f"http://127.0.0.1:{port}"
auth = {"Authorization": f"Bearer {token}"}

def call(method, path, body=None, headers=auth):
    data = None if body is None else json.dumps(body).encode()
    req = urllib.request.Request(base + path, data=data, method=method,
                                 headers={**headers, "Content-Type": "application/json"})
    try:
        with urllib.request.urlopen(req, timeout=30) as r:
            return r.status, r.read()
    except urllib.error.HTTPError as e:
        return e.code, e.read()

deadline = time.monotonic() + 120
while True:
    try:
        if call("GET", "/healthz", headers={})[0] == 200:
            break
    except OSError:
        pass
    if time.monotonic() > deadline:
        sys.exit("the API did not answer /healthz within 120 s")
    time.sleep(1)
status, _ = call("GET", "/studies", headers={})
assert status == 401, f"no token: expected 401, got {status}"
print("  no token: 401")
study = {
    "name": "podman-check",
    "reference": {"cell": [0.015, 0.015, 0.03], "output_interval": 2e-3, "platen_speed": 0.02,
                  "unconfined": False, "dt": 3e-5,
                  "pair_law": {"type": "BilinearAdhesive", "k1": 5e3, "k2": 2.5e4, "f0": -0.05}},
    "coarse_radii": [3.1e-3],
    "rules": ["paper"],
}
status, body = call("POST", "/studies", study)
assert status == 202, (status, body)
sid = json.loads(body)["id"]
print(f"  submitted {sid}")
t = time.monotonic()
while True:
    s = json.loads(call("GET", f"/studies/{sid}")[1])
    if s["status"] in ("succeeded", "failed", "cancelled"):
        break
    if time.monotonic() - t > 900:
        sys.exit(f"the study did not finish within 900 s: {s}")
    time.sleep(2)
assert s["status"] == "succeeded", s
print(f"  succeeded after {time.monotonic() - t:.0f} s (engine run time {s['run_time']:.1f} s)")
status, png = call("GET", f"/studies/{sid}/plots/stress_strain.png")
assert status == 200 and png[:8] == b"\x89PNG\r\n\x1a\n", (status, png[:100])
with open(f"{work}/stress_strain.png", "wb") as f:
    f.write(png)
print(f"  plot: {len(png)} bytes of PNG, saved to {work}/stress_strain.png")
status, h5 = call("GET", f"/studies/{sid}/results.h5")
assert status == 200 and h5[:8] == b"\x89HDF\r\n\x1a\n", status
print(f"  results.h5: {len(h5)} bytes")
PY
stamp "podman check passed ($("$PODMAN_COMPOSE" --version | head -n 1), $(podman --version))"
