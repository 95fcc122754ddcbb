// The PACS panel: the server's PACS names, a study search, a study's series,
// and a series loaded as a volume (its progress in the banner).
import type { VolumeInfo } from "../gen/cinevol/v1/service_pb.js";
import type { Api } from "./api.js";
import { plainWords } from "./words.js";

const $ = <T extends HTMLElement>(id: string) => document.getElementById(id) as T;

export class PacsPanel {
  constructor(private readonly api: Api, private readonly loaded: (volume: VolumeInfo) => void,
              private readonly banner: (text: string) => void, private readonly error: (text: string) => void) {}

  async start(): Promise<void> {
    try {
      const { names } = await this.api.pacs.listPacs({});
      if (names.length === 0) return;
      $<HTMLSelectElement>("pacs-name").replaceChildren(...names.map((n) => new Option(n, n)));
      $("pacs").hidden = false;
      $("pacs-search").addEventListener("click", () => void this.search());
    } catch {
      // A server without PACS (or an older one) shows no panel.
    }
  }

  private pacs(): string {
    return $<HTMLSelectElement>("pacs-name").value;
  }

  private async search(): Promise<void> {
    const query = $<HTMLInputElement>("pacs-query").value.trim();
    const looksLikeId = /\d/.test(query);
    try {
      const { studies } = await this.api.pacs.searchStudies({
        pacs: this.pacs(), patientId: looksLikeId ? query : "", patientName: looksLikeId || !query ? "" : `${query}*`,
      });
      this.list(studies.map((s) => ({
        text: `${s.patientName || "(no name)"} · ${s.studyDate} · ${s.description || s.modalities.join("/")}`,
        open: () => void this.series(s.studyUid),
      })), "No study found.");
    } catch (e) {
      this.error(plainWords(e));
    }
  }

  private async series(studyUid: string): Promise<void> {
    try {
      const { series } = await this.api.pacs.searchSeries({ pacs: this.pacs(), studyUid });
      this.list(series.map((s) => ({
        text: `${s.modality} · ${s.description || "(no description)"} · ${s.instanceCount ?? "?"} images`,
        open: () => void this.load(studyUid, s.seriesUid),
      })), "The study has no series.");
    } catch (e) {
      this.error(plainWords(e));
    }
  }

  private async load(studyUid: string, seriesUid: string): Promise<void> {
    try {
      // Refused by default, as on the server: a series with missing slices is resampled only when asked.
      const resampleUneven = ($("pacs-resample-uneven") as HTMLInputElement).checked;
      for await (const update of this.api.pacs.loadSeries({ pacs: this.pacs(), studyUid, seriesUid, resampleUneven })) {
        if (update.update.case === "progress") {
          const p = update.update.value;
          this.banner(`Loading the series: ${p.stage} ${p.instancesDone}/${p.instancesTotal} images`);
        } else if (update.update.case === "volume") {
          this.banner("");
          this.loaded(update.update.value);
        }
      }
    } catch (e) {
      this.banner("");
      this.error(plainWords(e));
    }
  }

  private list(items: { text: string; open: () => void }[], empty: string): void {
    $("pacs-results").replaceChildren(...(items.length ? items : [{ text: empty, open: () => {} }]).map((item) => {
      const li = document.createElement("li"), button = document.createElement("button");
      button.type = "button";
      button.textContent = item.text;
      button.addEventListener("click", item.open);
      li.append(button);
      return li;
    }));
  }
}
