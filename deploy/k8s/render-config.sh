#!/bin/sh
# Writes one cluster member's sculptd configuration from the shared template and the pod's
# identity. Run by the StatefulSet's init container (sculptd.yaml); also runnable by hand:
#   POD_NAME=sculptd-0 POD_NAMESPACE=sculpt SERVICE=sculptd SCULPT_PEER_TOKEN=... \
#     sh render-config.sh member.toml.in /tmp/sculptd.toml
# The template's @MEMBER@, @ADVERTISE_HOST@ and @PEER_TOKEN@ are replaced: the member is named
# after its pod (a StatefulSet keeps the name across restarts, so the member keeps its scene and
# standby copy), other members send clients to its stable DNS name under the headless service,
# and the peer token (cluster.peer_token, from the Secret sculpt-tokens) is the members' shared
# secret. The rendered file holds that secret: it is written readable by its owner only, and
# the token is never echoed.
set -eu
template=${1:?usage: render-config.sh TEMPLATE OUT}
out=${2:?usage: render-config.sh TEMPLATE OUT}
: "${POD_NAME:?POD_NAME is not set (downward API metadata.name)}"
: "${POD_NAMESPACE:?POD_NAMESPACE is not set (downward API metadata.namespace)}"
: "${SERVICE:?SERVICE is not set (the headless service of the StatefulSet)}"
: "${SCULPT_PEER_TOKEN:?SCULPT_PEER_TOKEN is not set (key peer of the Secret sculpt-tokens)}"
case "$POD_NAME" in
  *[!A-Za-z0-9._-]*) echo "render-config: POD_NAME=$POD_NAME is not [A-Za-z0-9._-]" >&2; exit 2 ;;
esac
# Characters that need no quoting in TOML or sed (openssl rand -hex / -base64 give these).
case "$SCULPT_PEER_TOKEN" in
  *[!A-Za-z0-9._~+/=-]*)
    echo "render-config: SCULPT_PEER_TOKEN has characters outside [A-Za-z0-9._~+/=-]" >&2; exit 2 ;;
esac
host="$POD_NAME.$SERVICE.$POD_NAMESPACE.svc.cluster.local"
tmp="$out.tmp"
umask 077
sed -e "s/@MEMBER@/$POD_NAME/g" -e "s/@ADVERTISE_HOST@/$host/g" \
  -e "s|@PEER_TOKEN@|$SCULPT_PEER_TOKEN|g" "$template" > "$tmp"
mv "$tmp" "$out"
echo "render-config: member $POD_NAME advertised as $host"
