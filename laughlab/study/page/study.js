/* laughlab's study page: a jsPsych 8 timeline built from design.js (window.STUDY).
 *
 * The participant comes from the URL (?participant=N), a recruitment panel's ID in it (?PROLIFIC_PID=...,
 * given a number by `study serve`: api/assign) or a start form.  With `study serve`
 * behind the page every rating is posted as soon as it is given (POST api/response) and the
 * server answers which trials are already done, so a closed tab resumes where it stopped;
 * on a static host the answers stay in this browser (localStorage) and the end page offers
 * them as a CSV file, in the columns `study analyze` reads.  Keys: 1..9 choose a point of the
 * current question, Enter goes on; arrows move a slider; Tab, Space and Enter work throughout.
 */
"use strict";
(function () {
  const S = window.STUDY;
  const COLUMNS = ["participant", "order_row", "trial", "stimulus", "condition", "audio_id", "kind", "question",
                   "value", "text", "expected", "rt_ms", "shown_at", "answered_at", "received_at", "session",
                   "user_agent"];
  const params = new URLSearchParams(window.location.search);
  const session = (window.crypto && crypto.randomUUID) ? crypto.randomUUID()
    : Date.now().toString(16) + Math.random().toString(16).slice(2);
  const ua = navigator.userAgent;
  // refused: posts the server refused (4xx); given: of them, answers already stored (409: another tab of the page);
  // kept: this page's trials the server stored
  // key: the participant's key the server gave this browser with their consent (every later post carries it)
  const state = {server: false, rows: [], pending: [], flushing: null, keys: null, refused: 0, given: 0, kept: 0,
                 key: null, p: null};
  const now = () => new Date().toISOString();
  const esc = (s) => String(s).replace(/[&<>"']/g, (c) => ({"&": "&amp;", "<": "&lt;", ">": "&gt;", '"': "&quot;",
                                                              "'": "&#39;"}[c]));

  // -- storage: the server first, this browser always ------------------------------------------------------------
  const storeKey = (p) => `laughlab-study-${S.id}-p${p}`;
  function saveLocal(p) {
    try { localStorage.setItem(storeKey(p), JSON.stringify(state.rows)); } catch (e) { /* private mode: CSV only */ }
  }
  function loadLocal(p) {
    try { return JSON.parse(localStorage.getItem(storeKey(p)) || "[]"); } catch (e) { return []; }
  }
  const keyName = (p) => storeKey(p) + "-key";
  function keepKey(key) {   // the key of this browser's participant: kept for a reload, sent with every post
    state.key = key;
    try { localStorage.setItem(keyName(state.p), key); } catch (e) { /* private mode: this page's life only */ }
  }
  async function api(path, body) {
    try {
      const r = await fetch(path, {method: "POST", headers: {"Content-Type": "application/json"},
                                   body: JSON.stringify(body), keepalive: true, cache: "no-store"});
      let data = null;
      try { data = await r.json(); } catch (e) { data = null; }
      return {ok: r.ok, status: r.status, data: data};
    } catch (e) {
      return {ok: false, status: 0, data: null};
    }
  }
  function send(path, body, onRefused) {  // queued in order; a network failure is retried with the next post
    if (!state.server) return Promise.resolve(true);
    state.pending.push({path: path, body: body, tried: false, onRefused: onRefused});
    return flush();
  }
  function flush() {
    if (state.flushing) return state.flushing.then(() => (state.pending.length ? flush() : true));
    state.flushing = (async () => {
      while (state.pending.length) {
        const post = state.pending[0];
        const r = await api(post.path, state.key ? Object.assign({key: state.key}, post.body) : post.body);
        if (r.ok && r.data && r.data.key) keepKey(r.data.key);
        if (r.status === 0 || r.status >= 500) {  // keep it for the next try; the server may have stored it
          post.tried = true;
          return false;
        }
        // a 409 on a retry: the first try reached the server and only its reply was lost (a diff review: it was
        // called another tab's answer); otherwise not stored, and the end page says so (a review: it said "All
        // your answers are saved")
        // this page's answers the server stored (a 409 on a retry: its first try was)
        if ((r.ok || (r.status === 409 && post.tried)) && post.path === "api/response") state.kept += 1;
        if (!r.ok && !(r.status === 409 && post.tried)) {
          console.warn(`laughlab study: ${post.path} refused (${r.status}): ${r.data && r.data.error}`);
          if (r.status === 409) state.given += 1; else state.refused += 1;
          if (post.onRefused) post.onRefused(r);
        }
        state.pending.shift();
      }
      return true;
    })().finally(() => { state.flushing = null; });
    return state.flushing;
  }
  function keep(p, P, t, kind, question, value, extra) {
    const row = Object.assign({participant: Number(p), order_row: P.order_row, trial: t ? t.trial : 0,
                               stimulus: t ? t.stimulus : "", condition: t ? t.condition : "",
                               audio_id: t ? t.audio_id : "", kind: kind, question: question, value: value,
                               text: "", expected: "", rt_ms: "", shown_at: "", answered_at: now(),
                               received_at: "", session: session, user_agent: ua}, extra || {});
    state.rows.push(row);
    saveLocal(p);
  }
  function csv() {
    const cell = (v) => {
      const s = v === null || v === undefined ? "" : String(v);
      return /[",\n\r]/.test(s) ? '"' + s.replace(/"/g, '""') + '"' : s;
    };
    return [COLUMNS.join(",")].concat(state.rows.map((r) => COLUMNS.map((c) => cell(r[c])).join(","))).join("\n") + "\n";
  }
  function download(p) {
    const url = URL.createObjectURL(new Blob([csv()], {type: "text/csv"}));
    const a = document.createElement("a");
    a.href = url;
    a.download = `participant_${String(p).padStart(3, "0")}_answers.csv`;
    document.body.appendChild(a);
    a.click();
    a.remove();
    setTimeout(() => URL.revokeObjectURL(url), 1000);
  }

  // -- keyboard ---------------------------------------------------------------------------------------------------
  function onKeys(handler) {
    offKeys();
    state.keys = handler;
    document.addEventListener("keydown", handler, true);
  }
  function offKeys() {
    if (state.keys) document.removeEventListener("keydown", state.keys, true);
    state.keys = null;
  }
  function likertKeys() {  // 1..9 choose a point of the focused (else the first unanswered) question; Enter submits
    const form = document.querySelector("#jspsych-survey-likert-form");
    const groups = Array.from(form.querySelectorAll(".jspsych-survey-likert-opts"));
    // each question names its radio group for a screen reader (an accessibility review: "radio 2", no question)
    form.querySelectorAll(".jspsych-survey-likert-statement").forEach((l, i) => {
      l.id = `study-q${i}`;
      const g = l.nextElementSibling;
      if (g && g.classList.contains("jspsych-survey-likert-opts")) {
        g.setAttribute("role", "radiogroup");
        g.setAttribute("aria-labelledby", l.id);
        g.querySelectorAll("li").forEach((li) => li.setAttribute("role", "none"));
      }
    });
    const open = () => groups.find((g) => !g.querySelector("input:checked"));
    const first = open();
    if (first) first.querySelector("input").focus();
    onKeys((e) => {
      if (e.key === "Enter") {
        e.preventDefault();
        e.stopPropagation();
        form.requestSubmit();
        return;
      }
      const k = e.key.length === 1 ? "123456789".indexOf(e.key) : -1;
      if (k < 0) return;
      const a = document.activeElement;
      const g = (a && a.closest && a.closest(".jspsych-survey-likert-opts")) || open() || groups[groups.length - 1];
      const radios = g.querySelectorAll("input[type=radio]");
      if (k >= radios.length) return;
      e.preventDefault();
      radios[k].checked = true;
      const next = open();
      (next ? next.querySelector("input") : form.querySelector("#jspsych-survey-likert-next")).focus();
    });
  }
  function sliderKeys() {  // the slider has the focus (arrows move it); Enter goes on once it was moved
    const slider = document.querySelector("#jspsych-html-slider-response-response");
    const question = document.querySelector(".study-question");
    if (question) {   // its question names it (an accessibility review: read as 'slider 50')
      question.id = "study-slider-question";
      slider.setAttribute("aria-labelledby", question.id);
    }
    const shown = document.querySelector("#study-slider-value");
    slider.addEventListener("input", () => { if (shown) shown.textContent = slider.value; });
    slider.focus();
    onKeys((e) => {
      if (e.key !== "Enter") return;
      e.preventDefault();
      const next = document.querySelector("#jspsych-html-slider-response-next");
      if (next && !next.disabled) next.click();
    });
  }
  function focusButton() {   // the page's way on: an instructions page's Next, else its first enabled button
    const b = document.querySelector("#jspsych-instructions-next") || document.querySelector(".jspsych-btn:not(:disabled)");
    if (b) b.focus();
  }

  // -- the timeline ---------------------------------------------------------------------------------------------
  function labels(q) {
    const n = S.points;
    return Array.from({length: n}, (_, j) => {
      const anchor = j === 0 ? q.labels[0] : (j === n - 1 ? q.labels[1] : "");
      return `<span class="study-point">${j + 1}</span><span class="study-anchor">${esc(anchor)}</span>`;
    });
  }
  function questionsOf(t) {
    const qs = S.questions.map((q) => ({id: q.id, prompt: q.prompt, labels: q.labels}));
    if (t.attention) {
      qs.splice(Math.min(1, qs.length), 0, {id: "attention", prompt: S.attention.prompt,
                                            labels: ["", ""]});
    }
    return qs;
  }
  function header(t, total, what) {
    // a heading: the trial and rating screens had none (an accessibility review)
    return `<h2 class="study-count" id="study-trial" data-trial="${t.trial}" data-stimulus="${esc(t.stimulus)}">` +
           `Video ${t.trial} of ${total}${what ? ": " + what : ""}</h2>`;
  }

  function ratings(jsPsych, p, P, t, total, shown) {
    const qs = questionsOf(t);
    const done = (values, rt) => {
      const answered = now();
      for (const q of qs) {
        const attention = q.id === "attention";
        keep(p, P, t, attention ? "attention" : "rating", q.id, values[q.id],
             {expected: attention ? S.attention.value : "", rt_ms: rt, shown_at: shown.at, answered_at: answered});
      }
      send("api/response", {participant: Number(p), session: session, trial: t.trial, stimulus: t.stimulus,
                            answers: values, rt_ms: rt, shown_at: shown.at, answered_at: answered, user_agent: ua});
      jsPsych.progressBar.progress = Math.min(1, ++shown.count.n / total);
    };
    if (S.scale === "likert") {
      return {
        type: jsPsychSurveyLikert, preamble: header(t, total, "your ratings"), button_label: "Continue",
        questions: qs.map((q) => ({prompt: esc(q.prompt), name: q.id, labels: labels(q), required: true})),
        on_load: likertKeys,
        on_finish: (data) => {
          offKeys();
          const values = {};
          for (const [k, v] of Object.entries(data.response)) values[k] = v + 1;
          done(values, data.rt);
        },
      };
    }
    const values = {};
    let rt = 0;
    return {timeline: qs.map((q, i) => ({
      type: jsPsychHtmlSliderResponse, stimulus: header(t, total, `question ${i + 1} of ${qs.length}`) +
        `<p class="study-question">${esc(q.prompt)}</p>`,
      labels: q.labels.map(esc), min: S.slider.min, max: S.slider.max, step: S.slider.step,
      slider_start: (S.slider.min + S.slider.max) / 2, require_movement: true, button_label: "Continue",
      // the value, shown: an attention item asks for one (an accessibility review: "choose 2" on an unlabelled 0-100)
      prompt: `<p class="study-value" aria-hidden="true">Your answer: <span id="study-slider-value">` +
        `${(S.slider.min + S.slider.max) / 2}</span></p>`,
      on_load: sliderKeys,
      on_finish: (data) => {
        offKeys();
        values[q.id] = Number(data.response);
        rt += data.rt;
        if (i === qs.length - 1) done(values, rt);
      },
    }))};
  }

  // after the last wrong try of the sound check (audio_check.on_fail: end): the study ends there, with thanks and
  // the panel's screen-out link (a review: it had gone on through every video, whose answers were then excluded)
  function returnLink(url) {   // back to the recruitment site (decline_url, screened_out_url), or ""
    return url ? `<p><a class="jspsych-btn study-link" href="${esc(url)}">Return to the recruitment site</a></p>` : "";
  }

  function screenedOut() {
    const back = returnLink(S.screened_out_url);
    return `<div class="study-text" id="study-screened-out"><h1>Thank you</h1><p role="status">The sound check ` +
      "could not confirm that you hear the videos' sound, which this study needs, so it ends here. Thank you for " +
      `your time; ${back ? "please return to the recruitment site:" : "you may close this page."}</p>${back}</div>`;
  }

  function audioCheck(jsPsych, p, P) {
    const word = S.audio_check.files[P.audio_check];
    const attempts = [];
    const norm = (s) => String(s).toLowerCase().replace(/[^a-z\u00c0-\u024f]/g, "");
    const fnv = (s) => {  // laughlab.study.design.word_check: the page holds the word's hash, not the word
      let h = 0x811c9dc5;
      for (const c of s) h = Math.imul(h ^ c.codePointAt(0), 0x01000193) >>> 0;
      return h.toString(16).padStart(8, "0");
    };
    const passed = () => attempts.length > 0 && fnv(norm(attempts[attempts.length - 1])) === word.check;
    const started = performance.now();
    const form = {
      type: jsPsychSurveyHtmlForm, autofocus: "study-word", button_label: "Continue",
      preamble: "<h2>Sound check</h2><p>Play the word, listen, and type the word you hear.</p>",
      html: () => `<p><audio id="study-audio" preload="auto" src="${esc(word.file)}"></audio>` +
        `<button type="button" id="study-play" class="jspsych-btn">&#9654; Play the word</button></p>` +
        `<p><label for="study-word">The word:</label> <input id="study-word" name="word" type="text" ` +
        `autocomplete="off" autocapitalize="none" spellcheck="false" required></p>` +
        (attempts.length ? `<p class="study-warn" role="alert">That was not the word: please check your sound and try again ` +
          `(${S.audio_check.attempts - attempts.length} tries left).</p>` : ""),
      on_load: () => {
        document.getElementById("study-play").addEventListener("click", () => {
          const a = document.getElementById("study-audio");
          a.currentTime = 0;
          // a participant who answers while it plays moves the page on: the play() cut short is not an error
          // (unhandled, it made a simulated participant's page raise and the study test fail now and then)
          a.play().catch(() => {});
          document.getElementById("study-word").focus();
        });
      },
      on_finish: (data) => {
        attempts.push(String(data.response.word || "").trim());
        if (passed() || attempts.length >= S.audio_check.attempts) {
          const rt = Math.round(performance.now() - started);
          keep(p, P, null, "audio_check", "audio_check", passed() ? 1 : 0,
               {text: attempts.join("|"), rt_ms: rt});
          send("api/check", {participant: Number(p), session: session, attempts: attempts, rt_ms: rt,
                             user_agent: ua});
          if (!passed() && S.audio_check_on_fail === "end") jsPsych.abortExperiment(screenedOut());
        }
      },
    };
    return {timeline: [form], loop_function: () => !passed() && attempts.length < S.audio_check.attempts};
  }

  function endPage(p) {
    const link = S.completion_url ? `<p><a class="jspsych-btn study-link" href="${esc(S.completion_url)}">` +
      "Finish and return</a></p>" : "";
    return {
      type: jsPsychHtmlButtonResponse, choices: [],
      stimulus: `<div class="study-end">${S.end}<p id="study-status" role="status">Saving your answers&hellip;</p>${link}` +
        `<p><button type="button" id="study-download" class="jspsych-btn">Download my answers (CSV)</button></p>` +
        "</div>",
      on_load: () => {
        document.getElementById("study-download").addEventListener("click", () => download(p));
        send("api/event", {participant: Number(p), session: session, event: "finish"}).then((ok) => {
          const status = document.getElementById("study-status");
          if (!status) return;
          const sent = ok && !state.pending.length;
          status.textContent = !state.server
            ? "This page has no server to save to: please download your answers and send the file as asked."
            : !sent ? "Some answers could not be sent: please download them and send the file as asked."
              : state.refused ? "Some of your answers were refused by the server: please download them and send " +
                "the file as asked."
                : state.given && !state.kept ? "Your answers here had all been given already in another tab or " +
                  "window of this page: those are kept, and nothing from this one."
                  : state.given ? "Some of your answers had already been given in another tab or window of this " +
                    "page: the first ones given are kept, and the rest are saved."
                    : "All your answers are saved.";
          status.dataset.saved = String(state.server && sent && !state.refused && !state.given);
        });
        focusButton();
      },
    };
  }

  function run(p, P, done, checked, consented) {
    const total = P.trials.length;
    if (checked === false && S.audio_check_on_fail === "end") {   // back after a failed sound check: the end again
      initJsPsych().run([{type: jsPsychHtmlButtonResponse, choices: [], stimulus: screenedOut()}]);
      return;
    }
    const jsPsych = initJsPsych({show_progress_bar: true, auto_update_progress_bar: false,
                                 message_progress_bar: "Progress"});
    const todo = P.trials.filter((t) => !done.has(t.trial));
    const count = {n: total - todo.length};
    const fresh = count.n === 0 && checked === null;
    const timeline = [{type: jsPsychPreload, video: todo.map((t) => t.file), continue_after_error: true,
                       audio: checked !== null ? [] : [S.audio_check.files[P.audio_check].file],
                       message: "<p>Loading the videos&hellip;</p>"}];
    // the server knows whether this participant gave consent (it stores nothing before it); a static host: a
    // fresh start asks
    if (consented === null ? fresh : !consented) {
      timeline.push({
        type: jsPsychHtmlButtonResponse, choices: ["I agree", "I do not agree"], on_load: focusButton,
        stimulus: `<div class="study-text"><h1>${esc(S.title)}</h1>${S.consent}</div>`,
        on_finish: (data) => {
          const agree = data.response === 0;
          // the participant's key, this browser's own, before the consent is posted (it carries it; a reload right
          // after finds it here)
          if (agree && !state.key) {
            const bytes = new Uint8Array(18);
            crypto.getRandomValues(bytes);
            keepKey(Array.from(bytes, (b) => b.toString(16).padStart(2, "0")).join(""));
          }
          // a consent the server refuses (the panel's place went to another after half an hour) is said, not
          // passed over into the study (an accessibility review)
          send("api/event", {participant: Number(p), session: session, event: agree ? "consent" : "decline"},
               (r) => { if (r.status === 409 && r.data && r.data.error) fatal(r.data.error); });
          // a panel's participant returns the study there (decline_url: e.g. Prolific's no-consent code)
          const back = returnLink(S.decline_url);
          if (!agree) jsPsych.abortExperiment(`<p>You chose not to take part. Thank you; ${back ? "please return " +
            "the study on the recruitment site:" : "you may close this page."}</p>${back}`);
        },
      });
    }
    if (fresh) {
      timeline.push({type: jsPsychInstructions, show_clickable_nav: true, key_forward: "ArrowRight",
                     key_backward: "ArrowLeft", button_label_next: "Next", button_label_previous: "Back",   // jsPsych adds &lt; and &gt;
                     pages: S.instructions.map((s) => `<div class="study-text">${s}</div>`), on_load: focusButton,
                     on_page_change: focusButton});
    } else {
      timeline.push({type: jsPsychHtmlButtonResponse, choices: ["Go on"], on_load: focusButton,
                     stimulus: `<div class="study-text"><h1>Welcome back</h1><p>Your answers so far are saved; ` +
                       (todo.length ? `the study goes on with video ${todo[0].trial} of ${total}.`
                         : "you have rated every video already: thank you.") + "</p></div>"});
    }
    if (checked === null) timeline.push(audioCheck(jsPsych, p, P));
    for (const t of todo) {
      const shown = {at: "", count: count};
      timeline.push({
        type: jsPsychVideoKeyboardResponse, stimulus: [t.file], choices: "NO_KEYS", autoplay: true, controls: false,
        trial_ends_after_video: true, response_allowed_while_playing: false, prompt: header(t, total, ""),
        on_load: () => {
          shown.at = now();
          const v = document.querySelector("#jspsych-video-keyboard-response-stimulus");
          v.setAttribute("playsinline", "");
          const played = v.play();
          if (played) played.catch(() => { v.controls = true; });  // autoplay refused: the participant presses play
        },
      });
      timeline.push(ratings(jsPsych, p, P, t, total, shown));
    }
    timeline.push(endPage(p));
    jsPsych.run(timeline).then(() => { jsPsych.progressBar.progress = count.n / total; });
    jsPsych.progressBar.progress = count.n / total;
  }

  function startForm(message) {
    const jsPsych = initJsPsych();
    jsPsych.run([{
      type: jsPsychSurveyHtmlForm, autofocus: "study-participant", button_label: "Start",
      preamble: `<div class="study-text"><h1>${esc(S.title)}</h1>${message ? `<p class="study-warn" role="alert">${esc(message)}</p>` : ""}</div>`,
      html: '<p><label for="study-participant">Your participant number:</label> ' +
        '<input id="study-participant" name="participant" type="number" min="1" step="1" inputmode="numeric" required></p>',
      on_finish: (data) => {
        params.set("participant", String(parseInt(data.response.participant, 10)));
        window.location.search = params.toString();
      },
    }]);
  }

  function fatal(message) {
    document.body.innerHTML = `<div class="study-text study-fatal"><h1>${esc(S.title)}</h1><p>${esc(message)}</p></div>`;
  }

  // a recruitment panel's ID in the URL: Prolific's PROLIFIC_PID, MTurk's workerId, or external_id
  const PANEL_KEYS = ["PROLIFIC_PID", "workerId", "external_id"];
  const panelKey = PANEL_KEYS.find((k) => params.has(k));
  const panelId = panelKey ? params.get(panelKey).trim() : null;

  // the server gives the panel's ID a participant number, the same one each time while it holds it; the page goes
  // on with it (a number in the URL that is not the ID's: another one given after half an hour without consent)
  async function assign(key, raw) {
    const r = await api("api/assign", {external_id: panelId, design: S.id});
    if (!(r.data && r.data.laughlab)) {
      fatal(`This link gives a ${key}, but this page is not served by the study's server, which gives each ` +
            "participant their number: please tell the researcher.");
    } else if (!r.ok) {
      fatal(r.data.error || "The study server refused this page.");
    } else if (String(r.data.participant) !== raw) {
      params.set("participant", String(r.data.participant));
      window.location.replace(window.location.pathname + "?" + params.toString());
    } else {
      return true;
    }
    return false;
  }

  async function main() {
    document.title = S.title;   // every screen was titled "Study"
    const raw = params.get("participant");
    if (panelKey && (!panelId || panelId.includes("{{"))) {  // a study-pilot review: an empty one gave the number form
      fatal(`This link's ${panelKey} is ${panelId ? "not filled in by the recruitment site" : "empty"}: please ` +
            "return to the recruitment site and tell the researcher.");
      return;
    }
    if (panelKey && !(await assign(panelKey, raw))) return;
    const p = raw && /^\d+$/.test(raw) ? String(parseInt(raw, 10)) : null;
    if (!p || !S.participants[p]) {
      startForm(raw ? `Participant ${raw} is not part of this study; please check the number.` : "");
      return;
    }
    const P = S.participants[p];
    state.rows = loadLocal(p);
    state.p = p;
    try { state.key = localStorage.getItem(keyName(p)); } catch (e) { state.key = null; }
    let consented = null;
    const begin = {participant: Number(p), session: session, design: S.id, user_agent: ua};
    if (panelId) begin.external_id = panelId;   // a number given to a panel's ID answers to it only
    if (state.key) begin.key = state.key;
    const r = await api("api/start", begin);
    const done = new Set();
    let checked = null;   // the sound check: null not done, true passed, false failed
    if (r.data && r.data.laughlab) {
      if (!r.ok) { fatal(r.data.error || "The study server refused this page."); return; }
      state.server = true;
      r.data.answered.forEach((t) => done.add(t));
      checked = r.data.audio_check ? r.data.audio_check_passed !== false : null;
      consented = Boolean(r.data.consented);
    } else {  // a static host: this browser's own record says what is done
      for (const row of state.rows) {
        if (row.kind === "audio_check") checked = Number(row.value) === 1; else done.add(row.trial);
      }
    }
    run(p, P, done, checked, consented);
  }

  window.laughlabStudy = {rows: () => state.rows, csv: csv, flush: flush, server: () => state.server};
  main();
})();
