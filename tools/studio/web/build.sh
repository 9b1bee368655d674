#!/usr/bin/env bash
# Builds the page of scopetrack-studio into OUTDIR:
#   OUTDIR/node_modules  npm ci of package-lock.json (only when the lockfile changed)
#   OUTDIR/gen           the console stream's FlatBuffers code (flatc --ts)
#   OUTDIR/src           the page's TypeScript, type-checked there (tsc --noEmit)
#   OUTDIR/dist          the bundled page (studio.js), index.html, studio.css: what the server serves
#   OUTDIR/test          the browser tests (their 'playwright-core' resolves from OUTDIR/node_modules)
# usage: tools/studio/web/build.sh OUTDIR      (CMake's target studio_web runs it into build/studio-web)
# FLATC may name another flatc (default: flatc on the PATH).
set -euo pipefail

die() { echo "studio web build: $*" >&2; exit 1; }

[[ $# -eq 1 ]] || die "usage: $0 OUTDIR"
web_dir="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
repo_dir="$(cd "$web_dir/../../.." && pwd)"
schema="$repo_dir/hal/stream/console_stream.fbs"
flatc="${FLATC:-flatc}"

command -v node >/dev/null 2>&1 || die "node is not installed (Node.js >= 20 is needed to build the page: apt-get install nodejs npm)"
command -v npm >/dev/null 2>&1 || die "npm is not installed (apt-get install npm)"
command -v "$flatc" >/dev/null 2>&1 || die "flatc ($flatc) is not installed (apt-get install flatbuffers-compiler, or set FLATC)"
node_major="$(node -p 'process.versions.node.split(".")[0]')"
(( node_major >= 20 )) || die "node $(node --version) is too old: Node.js >= 20 is needed"
[[ -f "$schema" ]] || die "the stream schema $schema is missing"

mkdir -p "$1"
out="$(cd "$1" && pwd)"

# 1. Dependencies: npm ci only when the lockfile differs from the one last installed.
stamp="$out/.npm-ci-stamp"
cp "$web_dir/package.json" "$web_dir/package-lock.json" "$out/"
if [[ ! -d "$out/node_modules" || ! -f "$stamp" ]] || ! cmp -s "$web_dir/package-lock.json" "$stamp"; then
  echo "studio web build: npm ci into $out"
  rm -f "$stamp"
  (cd "$out" && npm ci --no-audit --no-fund) || die "npm ci failed in $out (is the npm registry reachable?)"
  cp "$web_dir/package-lock.json" "$stamp"
fi
[[ -x "$out/node_modules/.bin/esbuild" ]] || die "esbuild is missing from $out/node_modules (delete $stamp and run again)"

# 2. The stream's TypeScript code, fresh from the schema.
rm -rf "$out/gen"
"$flatc" --ts -o "$out/gen" "$schema" || die "flatc --ts failed on $schema"

# 3. The sources beside node_modules, type-checked (esbuild only strips the
#    types): strict TypeScript against three's declarations and the generated code.
rm -rf "$out/src"
cp -r "$web_dir/src" "$out/src"
cat > "$out/tsconfig.json" <<'JSON'
{
  "compilerOptions": {
    "target": "es2020", "module": "es2020", "moduleResolution": "bundler", "strict": true,
    "noEmit": true, "skipLibCheck": true, "lib": ["es2020", "dom", "dom.iterable"],
    "paths": { "studio-gen/*": ["./gen/*"] }
  },
  "include": ["src/**/*.ts"]
}
JSON
"$out/node_modules/.bin/tsc" -p "$out/tsconfig.json" || die "the page's TypeScript does not type-check (above)"

# 4. The page: one bundle; 'studio-gen/...' imports name OUTDIR/gen, packages come from OUTDIR/node_modules.
rm -rf "$out/dist"
mkdir -p "$out/dist"
"$out/node_modules/.bin/esbuild" "$out/src/main.ts" \
  --bundle --format=esm --target=es2020 --minify --sourcemap --log-level=warning \
  --alias:studio-gen="$out/gen" \
  --outfile="$out/dist/studio.js" || die "esbuild failed to bundle $web_dir/src/main.ts"
cp "$web_dir/index.html" "$web_dir/studio.css" "$out/dist/"

# 5. The browser tests, beside node_modules.
rm -rf "$out/test"
mkdir -p "$out/test"
cp "$web_dir"/test/*.mjs "$out/test/"

echo "studio web build: page in $out/dist, tests in $out/test"
