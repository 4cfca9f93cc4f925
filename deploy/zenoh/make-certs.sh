#!/bin/sh
# A certificate authority for one hydromon site, and one certificate per role, with openssl.
#
#   deploy/zenoh/make-certs.sh DIR ROUTER_HOST [RIG_ID ...]
#
# writes into DIR (created; files that exist are kept, so it adds rigs to an existing CA):
#   ca.pem, ca.key            the site's CA (keep ca.key offline; every node needs ca.pem)
#   router.pem, router.key    the router: CN router, names ROUTER_HOST, localhost, 127.0.0.1
#   monitor.pem/.key, recorder.pem/.key, viewer.pem/.key
#                             one per role: CN monitor, recorder, viewer
#   RIG_ID.pem, RIG_ID.key    one per rig: CN = the rig id (the router's access control
#                             lets a certificate put only the keys of the rig it names)
# Keys are EC P-256 in PKCS#8, certificates valid DAYS days (default 825; set DAYS=... to change).
set -eu
if [ $# -lt 2 ]; then
    echo "usage: $0 DIR ROUTER_HOST [RIG_ID ...]" >&2
    exit 2
fi
dir=$1; host=$2; shift 2
days=${DAYS:-825}
mkdir -p "$dir"
umask 077

key() {  # key FILE
    [ -f "$1" ] || openssl genpkey -algorithm EC -pkeyopt ec_paramgen_curve:P-256 -out "$1" 2>/dev/null
}

if [ ! -f "$dir/ca.pem" ]; then
    key "$dir/ca.key"
    openssl req -x509 -new -key "$dir/ca.key" -sha256 -days "$days" -subj "/CN=hydromon site CA" \
        -addext "basicConstraints=critical,CA:TRUE" -addext "keyUsage=critical,keyCertSign,cRLSign" \
        -out "$dir/ca.pem"
fi

leaf() {  # leaf NAME COMMON_NAME EXTENSIONS
    [ -f "$dir/$1.pem" ] && return 0
    key "$dir/$1.key"
    printf '%s\n' "basicConstraints=critical,CA:FALSE" "keyUsage=critical,digitalSignature" "$3" > "$dir/$1.ext"
    openssl req -new -key "$dir/$1.key" -subj "/CN=$2" -out "$dir/$1.csr"
    openssl x509 -req -in "$dir/$1.csr" -CA "$dir/ca.pem" -CAkey "$dir/ca.key" -CAcreateserial -sha256 \
        -days "$days" -extfile "$dir/$1.ext" -out "$dir/$1.pem" 2>/dev/null
    rm -f "$dir/$1.csr" "$dir/$1.ext"
}

case $host in
    *[!0-9.]*) san="DNS:$host" ;;
    *) san="IP:$host" ;;
esac
leaf router router "extendedKeyUsage=serverAuth,clientAuth
subjectAltName=$san,DNS:localhost,IP:127.0.0.1"
for role in monitor recorder viewer; do
    leaf "$role" "$role" "extendedKeyUsage=clientAuth"
done
for rig in "$@"; do
    leaf "$rig" "$rig" "extendedKeyUsage=clientAuth"
done
chmod 644 "$dir"/*.pem
echo "certificates in $dir: $(cd "$dir" && ls *.pem | tr '\n' ' ')"
