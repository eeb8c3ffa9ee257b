// A tiny typed client of the stereo distance service: its request and answer types come from
// `openapi-typescript` run on the served /openapi.json (schema.d.ts, generated, not committed),
// and this file compiles under `tsc --strict`. scripts/contract/clients runs it against a live server:
//
//   node target/clients/typescript/build/client.js http://127.0.0.1:8080 [TOKEN]
//
// With a TOKEN (a service started with API_TOKENS), every request carries it as a bearer token.
//
// It asks for one distance, a table (JSON and CSV) and a refused request, checks the numbers and
// prints what it got.
import type { components, paths } from "./schema.js";

type Problem = components["schemas"]["Problem"];
type DistanceRequest = components["schemas"]["DistanceRequest"];
type DistanceResponse = components["schemas"]["DistanceResponse"];
type TableRequest = paths["/table"]["post"]["requestBody"]["content"]["application/json"];
type TableResponse = paths["/table"]["post"]["responses"][200]["content"]["application/json"];

/** An answer: the 200's body, or the problem+json of any error status. */
type Answer<T> = { ok: true; body: T } | { ok: false; status: number; problem: Problem };

/** The service at `base`, one method per operation this client uses. */
export class StereoClient {
  constructor(
    private readonly base: string,
    private readonly token?: string,
  ) {}

  private async post(path: keyof paths, body: unknown, accept: string): Promise<Response> {
    const headers: Record<string, string> = { "content-type": "application/json", accept };
    if (this.token) headers.authorization = `Bearer ${this.token}`;
    return fetch(new URL(path, this.base), {
      method: "POST",
      headers,
      body: JSON.stringify(body),
    });
  }

  private async json<T>(path: keyof paths, body: unknown): Promise<Answer<T>> {
    const response = await this.post(path, body, "application/json");
    if (response.ok) return { ok: true, body: (await response.json()) as T };
    return { ok: false, status: response.status, problem: (await response.json()) as Problem };
  }

  /** POST /distance for one correspondence. */
  distance(request: DistanceRequest): Promise<Answer<DistanceResponse>> {
    return this.json<DistanceResponse>("/distance", request);
  }

  /** POST /table, as JSON. */
  table(request: TableRequest): Promise<Answer<TableResponse>> {
    return this.json<TableResponse>("/table", request);
  }

  /** POST /table.csv: the same table as CSV text. */
  async tableCsv(request: TableRequest): Promise<string> {
    const response = await this.post("/table.csv", request, "text/csv");
    if (!response.ok) throw new Error(`POST /table.csv answered ${response.status}`);
    return response.text();
  }
}

function check(condition: boolean, what: string): void {
  if (!condition) throw new Error(`check failed: ${what}`);
}

function close(actual: number, expected: number, what: string): void {
  check(Math.abs(actual - expected) <= 1e-9 * Math.abs(expected), `${what}: ${actual} is not ${expected}`);
}

async function main(): Promise<void> {
  const base = process.argv[2] ?? "http://127.0.0.1:8080";
  const client = new StereoClient(base, process.argv[3]);

  // KITTI's rig, a feature 10 px apart: Z = 721.5377 px × 0.54 m / 10 px.
  const kitti: DistanceRequest = {
    focal_length_px: 721.5377,
    baseline: 0.54,
    unit: "m",
    cx: 609.5593,
    cy: 172.854,
    x_left: 620,
    x_right: 610,
  };
  const distance = await client.distance(kitti);
  if (!distance.ok) throw new Error(`POST /distance: ${distance.problem.detail}`);
  close(distance.body.distance, (721.5377 * 0.54) / 10, "distance");
  console.log(`distance: ${distance.body.distance} ${distance.body.unit} ± ${distance.body.depth_error}`);

  const request: TableRequest = {
    focal_length_px: 721.5377,
    baseline: 0.54,
    unit: "m",
    cx: 609.5593,
    cy: 172.854,
    disparity_min: 1,
    disparity_max: 100,
    steps: 4,
  };
  const table = await client.table(request);
  if (!table.ok) throw new Error(`POST /table: ${table.problem.detail}`);
  check(table.body.rows.length === 4, "four rows");
  for (const row of table.body.rows) close(row.distance * row.disparity_px, 721.5377 * 0.54, "Z·d = f·B");
  const csv = (await client.tableCsv(request)).trim().split("\r\n");
  check(csv.length === 5, "a header and four lines");
  check(csv[0]?.startsWith("distance_m,disparity_px") ?? false, `CSV header: ${csv[0]}`);
  console.log(`table: ${table.body.rows.length} rows; CSV header ${csv[0]}`);

  const refused = await client.distance({ ...kitti, baseline: 0 });
  if (refused.ok) throw new Error("a zero baseline was accepted");
  check(refused.status === 422 && refused.problem.errors[0]?.field === "baseline", "422 names baseline");
  console.log(`refused: ${refused.status} ${refused.problem.detail}`);
}

main().catch((error: unknown) => {
  console.error(error);
  process.exit(1);
});
