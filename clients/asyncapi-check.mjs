// Parses an AsyncAPI document with the official parser (@asyncapi/parser 3) and fails on any
// diagnostic of severity error or warning (0 and 1), printing each with its path.
//
//   node clients/asyncapi-check.mjs openapi/asyncapi.yaml
import { readFileSync } from "node:fs";
import { Parser } from "@asyncapi/parser";

const file = process.argv[2];
const { document, diagnostics } = await new Parser().parse(readFileSync(file, "utf8"));
const serious = diagnostics.filter((d) => d.severity <= 1);
for (const d of serious) {
  console.error(`${file}: ${d.code} at ${d.path.join(".") || "(root)"}: ${d.message}`);
}
if (!document || serious.length > 0) {
  console.error(`${file}: ${serious.length} errors or warnings; the document ${document ? "parsed" : "did not parse"}`);
  process.exit(1);
}
console.log(`${file}: AsyncAPI ${document.version()} parsed, ${diagnostics.length} hints`);
