// The PACS panel: the server's PACS names, a study search, a study's series,
// and a series opened: images loaded as a volume (its progress in the
// banner), a measurement report (SR) as the session's measurements, a
// segmentation (SEG) as the open volume's labels, a presentation state (PR)
// as the series it presents in its scene; and the session's measurements
// stored back as a report (docs/web.md).
import type { Measurement, Scene } from "../gen/cinevol/v1/scene_pb.js";
import type { VolumeInfo } from "../gen/cinevol/v1/service_pb.js";
import type { Api } from "./api.js";
import type { IidRequest } from "./iid.js";
import { plainWords } from "./words.js";

const $ = <T extends HTMLElement>(id: string) => document.getElementById(id) as T;

/** What the panel acts on in the rest of the page. */
export interface PacsPanelHooks {
  /** A volume loaded; `scene`: the presentation state's it is opened in. */
  loaded: (volume: VolumeInfo, scene?: Scene) => void;
  measured: (measurements: readonly Measurement[]) => void;
  sessionId: () => string | undefined;
  volumeId: () => string | undefined;
  banner: (text: string) => void;
  error: (text: string) => void;
}

/** What a study holds that is not images to look at: reports, segmentations, presentation states, renders. */
const NOT_IMAGES = new Set(["SR", "SEG", "PR", "KO", "DOC", "OT"]);

export class PacsPanel {
  private names: string[] = [];

  constructor(private readonly api: Api, private readonly hooks: PacsPanelHooks) {}

  async start(): Promise<void> {
    try {
      const { names } = await this.api.pacs.listPacs({});
      this.names = names;
      if (names.length === 0) return;
      $<HTMLSelectElement>("pacs-name").replaceChildren(...names.map((n) => new Option(n, n)));
      $("pacs").hidden = false;
      $("pacs-search").addEventListener("click", () => void this.search());
      $("pacs-store-measurements").addEventListener("click", () => void this.storeMeasurements());
    } catch {
      // A server without PACS (or an older one) shows no panel.
    }
  }

  /**
   * An IHE IID launch (iid.ts): the study it names (its first, by UID or accession number) or the patient's most
   * recent, opened as its largest image series in the default preset; what cannot be found is said in words.
   */
  async openIid(iid: IidRequest): Promise<void> {
    const pacs = iid.pacs ?? this.names[0];
    if (!pacs || !this.names.includes(pacs)) {
      return this.hooks.error(pacs ? `The server names no PACS '${pacs}' (it names ${this.names.join(", ") || "none"}).`
                                   : "The server names no PACS, so a launch naming a study has nothing to open.");
    }
    $<HTMLSelectElement>("pacs-name").value = pacs;
    try {
      const studyUid = await this.iidStudy(pacs, iid);
      if (!studyUid) return this.hooks.error(`PACS '${pacs}' has no study for this launch.`);
      await this.series(studyUid);  // listed in the panel too
      const { series } = await this.api.pacs.searchSeries({ pacs, studyUid });
      const images = series.filter((s) => !NOT_IMAGES.has(s.modality))
        .sort((a, b) => Number(b.instanceCount ?? 0n) - Number(a.instanceCount ?? 0n));
      if (images.length === 0) return this.hooks.error(`Study ${studyUid} on '${pacs}' holds no images to show.`);
      await this.load(studyUid, images[0].seriesUid, false);
    } catch (e) {
      this.hooks.error(plainWords(e));
    }
  }

  private async iidStudy(pacs: string, iid: IidRequest): Promise<string | undefined> {
    if (iid.studyUids.length > 0) return iid.studyUids[0];
    const { studies } = await this.api.pacs.searchStudies(iid.requestType === "STUDY"
      ? { pacs, accessionNumber: iid.accessionNumbers[0] } : { pacs, patientId: iid.patientId });
    return [...studies].sort((a, b) => b.studyDate.localeCompare(a.studyDate))[0]?.studyUid;
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
      this.hooks.error(plainWords(e));
    }
  }

  private async series(studyUid: string): Promise<void> {
    try {
      const { series } = await this.api.pacs.searchSeries({ pacs: this.pacs(), studyUid });
      this.list(series.map((s) => ({
        text: `${s.modality} · ${s.description || "(no description)"} · ${s.instanceCount ?? "?"} images`,
        open: () => void (s.modality === "SR" ? this.loadMeasurements(studyUid, s.seriesUid)
                          : s.modality === "PR" ? this.loadPresentation(studyUid, s.seriesUid)
                          : this.load(studyUid, s.seriesUid, s.modality === "SEG")),
      })), "The study has no series.");
    } catch (e) {
      this.hooks.error(plainWords(e));
    }
  }

  /**
   * A series as a volume (in `scene` where given, its labels from the SEG series `labels` where named); a
   * segmentation as the open volume's labels.
   */
  private async load(studyUid: string, seriesUid: string, segmentation: boolean, scene?: Scene,
                     labels?: string): Promise<void> {
    const { banner, error, loaded } = this.hooks;
    const labelsFor = segmentation ? this.hooks.volumeId() ?? "" : "";
    if (segmentation && !labelsFor) return error("Open the images this segmentation belongs to first.");
    try {
      // Refused by default, as on the server: a series with missing slices is resampled only when asked.
      const resampleUneven = ($("pacs-resample-uneven") as HTMLInputElement).checked;
      for await (const update of this.api.pacs.loadSeries({ pacs: this.pacs(), studyUid, seriesUid, resampleUneven,
                                                            labelsFor })) {
        if (update.update.case === "progress") {
          const p = update.update.value;
          banner(`Loading the series: ${p.stage} ${p.instancesDone}/${p.instancesTotal} images`);
        } else if (update.update.case === "volume") {
          banner("");
          let volume = update.update.value;
          if (labels) {
            for await (const u of this.api.pacs.loadSeries({ pacs: this.pacs(), studyUid, seriesUid: labels,
                                                             labelsFor: volume.id })) {
              if (u.update.case === "volume") volume = u.update.value;
            }
          }
          loaded(volume, scene);
        }
      }
    } catch (e) {
      banner("");
      error(plainWords(e));
    }
  }

  /** A presentation state (a still's recipe, or another viewer's): the series it presents, opened in its scene. */
  private async loadPresentation(studyUid: string, seriesUid: string): Promise<void> {
    try {
      const presented = await this.api.pacs.loadPresentation({ pacs: this.pacs(), studyUid, seriesUid });
      await this.load(presented.studyUid, presented.seriesUid, false, presented.scene,
                      presented.labelsSeriesUid || undefined);
    } catch (e) {
      this.hooks.error(plainWords(e));
    }
  }

  /** A measurement report's distances and angles, as this session's measurements. */
  private async loadMeasurements(studyUid: string, seriesUid: string): Promise<void> {
    try {
      const report = await this.api.pacs.loadMeasurements({ pacs: this.pacs(), studyUid, seriesUid });
      this.hooks.measured(report.measurements);
      this.hooks.banner(`${report.measurements.length} measurement(s) from the report`);
    } catch (e) {
      this.hooks.error(plainWords(e));
    }
  }

  /** The session's measurements, stored in its study on the chosen PACS as a report. */
  private async storeMeasurements(): Promise<void> {
    const sessionId = this.hooks.sessionId();
    if (!sessionId) return this.hooks.error("No session is open: there is nothing to store.");
    try {
      const stored = await this.api.pacs.storeMeasurements({ sessionId, pacs: this.pacs() });
      this.hooks.banner(`Measurements stored on ${stored.pacs}: series ${stored.seriesUid}`);
    } catch (e) {
      this.hooks.error(plainWords(e));
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
