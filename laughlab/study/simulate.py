"""Simulated participants: headless Chromium (Playwright) doing the whole study, as people would.

``python -m laughlab study simulate URL`` (or the tests) opens one browser page per participant,
all at once, against a running ``study serve``: consent, instructions, the audio check (typing the
participant's word), every video to its end, every rating, the end page.  The answers come from a
known model (:func:`planted`): a base rating, the planted effect of each condition, a participant
offset and noise, rounded to the scale, so the analysis should recover the effect.  Half of the
participants use the keyboard only (keys 1..9, Enter, arrows), the others the mouse.
Behaviours to test the exclusions: ``careless`` (fails the attention items), ``straightline`` (the
same rating everywhere), ``deaf`` (types a wrong word at every try).

Playwright drives Debian's ``chromium`` (``executable_path``); Playwright's own browser download is
not needed.
"""
from __future__ import annotations

import asyncio
import logging
import math
import time
from dataclasses import dataclass, field

import numpy as np

from laughlab.core.errors import LaughlabError


@dataclass
class Given:
    """What one simulated participant answered (and whether the page said all was saved)."""
    participant: int
    answers: dict = field(default_factory=dict)  # (trial, question) -> value
    audio_attempts: list = field(default_factory=list)
    saved: bool | None = None
    status: str = ""  # the end page's line about saving
    screened_out: bool = False  # the page ended after a failed sound check (audio_check.on_fail: end)
    refused: bool = False  # the page refused the participant at once (its line in status)
    seconds: float = 0.0
    csv: str = ""  # the page's own record of the answers (its "Download my answers" CSV)


#: the planted model's base rating and spreads (points of the rating scale), recorded with each simulation
PLANTED_SPREAD = {"base": 4.0, "sd_participant": 0.5, "sd_noise": 0.6}


def planted(design: dict, effects: dict[str, float], base: float = PLANTED_SPREAD["base"],
            sd_participant: float = PLANTED_SPREAD["sd_participant"], sd_noise: float = PLANTED_SPREAD["sd_noise"],
            seed: int = 0):
    """answer(p, trial, question) from ``base + effects[condition] + u_p + e`` rounded and clipped to the scale."""
    from laughlab.study.design import scale_range

    lo, hi = scale_range(design)
    rng = np.random.default_rng(seed)
    offsets = {int(p): rng.normal(0, sd_participant) for p in sorted(design["participants"], key=int)}
    noise = {}

    def answer(p: int, trial: int, question: str) -> float:
        if question == "attention":
            return float(design["attention"]["value"])
        cond = design["participants"][str(p)]["trials"][trial - 1]["condition"]
        key = (p, trial, question)
        if key not in noise:
            noise[key] = float(np.random.default_rng([seed, p, trial, sum(map(ord, question))]).normal(0, sd_noise))
        v = base + effects.get(cond, 0.0) + offsets[p] + noise[key]
        return float(min(hi, max(lo, round(v)))) if design["scale"] == "likert" else float(min(hi, max(lo, v)))

    return answer


def launch_options() -> dict:
    from laughlab.viewer.browser import chromium

    return {"executable_path": chromium(), "headless": True,
            "args": ["--no-sandbox", "--autoplay-policy=no-user-gesture-required", "--mute-audio"]}


async def _click_or_key(page, keyboard: bool, key: str, selector: str) -> None:
    if keyboard:
        await page.keyboard.press(key)
    else:
        await page.click(selector)


async def participant(browser, url: str, design: dict, p: int, answer, keyboard: bool = False,
                      behaviour: str = "attentive", stop_after: int | None = None,
                      viewport=(1280, 720), timeout_s: float = 60.0) -> Given:
    """One participant from the first page to the end page (or until ``stop_after`` trials, then the tab closes)."""
    t0 = time.monotonic()
    given = Given(p)
    ctx = await browser.new_context(viewport={"width": viewport[0], "height": viewport[1]})
    page = await ctx.new_page()
    page.set_default_timeout(timeout_s * 1000)
    errors = []
    page.on("pageerror", lambda exc: errors.append(str(exc)))
    entry = design["participants"][str(p)]
    try:
        await page.goto(f"{url.rstrip('/')}/index.html?participant={p}")
        first = await page.wait_for_selector("button:has-text('I agree'), button:has-text('Go on'), "
                                             "#jspsych-instructions-next, #study-screened-out, .study-fatal")
        first_id, text = await first.get_attribute("id"), (await first.inner_text()).strip()
        if "study-fatal" in (await first.get_attribute("class") or ""):   # refused (another browser's participant)
            given.status, given.refused = text, True
            return given
        if first_id == "study-screened-out":   # back after a failed sound check
            pass
        elif first_id == "jspsych-instructions-next" or "agree" in text:
            if "agree" in text:   # not asked again by the server after an earlier consent
                await _click_or_key(page, keyboard, "Enter", "button:has-text('I agree')")
            for _ in design["instructions"]:
                await page.wait_for_selector("#jspsych-instructions-next")
                await _click_or_key(page, keyboard, "ArrowRight", "#jspsych-instructions-next")
        else:
            await _click_or_key(page, keyboard, "Enter", "button:has-text('Go on')")
        word = design["audio_check"]["files"][entry["audio_check"]]["answer"]
        for k in range(int(design["audio_check"]["attempts"])):
            box = await page.wait_for_selector("#study-word, #study-trial, #study-status, #study-screened-out")
            if await box.get_attribute("id") != "study-word":
                break
            typed = f"not{word}{k}" if behaviour == "deaf" else word
            if not keyboard:
                await page.click("#study-play")
            await page.fill("#study-word", typed)
            given.audio_attempts.append(typed)
            await _click_or_key(page, keyboard, "Enter", "#jspsych-survey-html-form-next")
            if behaviour != "deaf":
                break
            await page.wait_for_function("!document.querySelector('#study-word') || "
                                         "document.querySelector('#study-word').value === ''")
        done = 0
        while True:
            el = await page.wait_for_selector("#jspsych-survey-likert-form, #jspsych-html-slider-response-response, "
                                              "#study-status, #study-screened-out", timeout=timeout_s * 1000)
            if await el.get_attribute("id") in ("study-status", "study-screened-out"):
                given.screened_out = await el.get_attribute("id") == "study-screened-out"
                break
            if stop_after is not None and done >= stop_after:
                break
            trial = int(await page.get_attribute("#study-trial", "data-trial"))
            if design["scale"] == "likert":
                await _likert(page, design, p, trial, answer, keyboard, behaviour, given)
            else:
                await _sliders(page, design, p, trial, answer, behaviour, given)
            done += 1
            await page.wait_for_function(f"!document.querySelector('#study-trial[data-trial=\"{trial}\"]') || "
                                         "!document.querySelector('#jspsych-survey-likert-form, "
                                         "#jspsych-html-slider-response-response')")
        if stop_after is None and given.screened_out:
            given.status = (await page.text_content("#study-screened-out p")).strip()
            given.csv = await page.evaluate("window.laughlabStudy.csv()")
        elif stop_after is None:
            await page.wait_for_selector("#study-status[data-saved]")
            given.saved = await page.get_attribute("#study-status", "data-saved") == "true"
            given.status = await page.text_content("#study-status")
            given.csv = await page.evaluate("window.laughlabStudy.csv()")
    finally:
        if stop_after is not None:
            await page.wait_for_timeout(200)  # the last answer's post is on its way, as when a person closes the tab
        await ctx.close()
    if errors:
        raise LaughlabError(f"participant {p}: the page raised {errors[0]}")
    given.seconds = time.monotonic() - t0
    return given


def _value(design, p, trial, q, answer, behaviour) -> float:
    if behaviour == "straightline":
        return float(design["attention"]["value"]) if q == "attention" else 4.0
    if behaviour == "careless" and q == "attention":
        lo, hi = (1, design["points"]) if design["scale"] == "likert" else (design["slider"]["min"],
                                                                               design["slider"]["max"])
        return float(hi if design["attention"]["value"] != hi else lo)
    return answer(p, trial, q)


async def _likert(page, design, p, trial, answer, keyboard, behaviour, given) -> None:
    names = await page.eval_on_selector_all("#jspsych-survey-likert-form .jspsych-survey-likert-opts",
                                            "els => els.map(e => e.dataset.name)")
    for q in names:
        v = int(_value(design, p, trial, q, answer, behaviour))
        given.answers[(trial, q)] = float(v)
        if keyboard:  # the first unanswered question has the focus: a digit answers it
            await page.keyboard.press(str(v))
        else:
            await page.click(f'ul[data-name="{q}"] input[value="{v - 1}"]')
    await _click_or_key(page, keyboard, "Enter", "#jspsych-survey-likert-next")


async def _sliders(page, design, p, trial, answer, behaviour, given) -> None:
    qs = [q["id"] for q in design["questions"]]
    if design["participants"][str(p)]["trials"][trial - 1]["attention"]:
        qs.insert(min(1, len(qs)), "attention")
    for i, q in enumerate(qs):
        await page.wait_for_selector(f'#study-trial[data-trial="{trial}"]')
        v = _value(design, p, trial, q, answer, behaviour)
        step = design["slider"]["step"]
        v = design["slider"]["min"] + round((v - design["slider"]["min"]) / step) * step
        given.answers[(trial, q)] = float(v)
        await page.eval_on_selector("#jspsych-html-slider-response-response",
                                    "(el, v) => { el.value = v; el.dispatchEvent(new Event('change')); }", v)
        await page.keyboard.press("Enter")
        if i < len(qs) - 1:
            await page.wait_for_function(f"document.querySelector('.study-count') && "
                                         f"document.querySelector('.study-count').textContent.includes('question {i + 2} ')")


async def run(url: str, design: dict, participants: list[int], answer, behaviours: dict | None = None,
              stop_after: dict | None = None, viewport=(1280, 720)) -> dict[int, Given]:
    """All ``participants`` at once, each in its own browser context; what each answered."""
    from playwright.async_api import async_playwright

    behaviours, stop_after = behaviours or {}, stop_after or {}
    async with async_playwright() as pw:
        browser = await pw.chromium.launch(**launch_options())
        try:
            out = await asyncio.gather(*[
                participant(browser, url, design, p, answer, keyboard=(i % 2 == 1),
                            behaviour=behaviours.get(p, "attentive"), stop_after=stop_after.get(p),
                            viewport=viewport) for i, p in enumerate(participants)])
        finally:
            await browser.close()
    return {g.participant: g for g in out}


def browser_gone(exc: BaseException) -> bool:
    """Chromium or Playwright's driver ended under the simulation (killed, crashed; or a process-group Ctrl-C to a
    command started as a shell's background job, which ignores SIGINT itself): Playwright's errors, not a stop."""
    from laughlab.core import interrupts

    if interrupts.received is not None or not isinstance(exc, Exception):
        return False
    try:
        from playwright.async_api import Error
    except ImportError:
        return False
    return isinstance(exc, Error) or "Connection closed while reading from the driver" in str(exc)


def run_sync(*args, **kwargs) -> dict[int, Given]:
    """:func:`run` to its end.  A stop signal cancels it (``interrupts.run_coroutine``: the browser closes whole)
    and then raises ``KeyboardInterrupt``.  The pages' pending calls fail as the browser closes; asyncio would
    print each of them (hundreds of lines) before laughlab's one line, so they are let go quietly then."""
    from laughlab.core import interrupts

    def quiet_after_interrupt(loop, context):
        if interrupts.received is None:
            loop.default_exception_handler(context)

    try:
        return interrupts.run_coroutine(run(*args, **kwargs), quiet_after_interrupt)
    except BaseException as exc:
        # after a stop, or with the browser gone: the driver process is reaped after the loop closed, and asyncio logs
        # "Loop ... that handles pid ... is closed" and "Future exception was never retrieved" (Connection closed)
        if interrupts.received is not None or browser_gone(exc):
            logging.getLogger("asyncio").disabled = True
        raise


def parse_effects(text: str, design: dict) -> dict[str, float]:
    """``laugh_energy=1,laugh_concat=0.5`` -> {condition: points}; every condition named must exist."""
    out = {}
    for part in filter(None, (s.strip() for s in text.split(","))):
        cond, sep, val = part.partition("=")
        if not sep or cond not in design["conditions"]:
            raise LaughlabError(f"--effects wants CONDITION=POINTS with a condition of {', '.join(design['conditions'])}"
                                f" (got {part!r})")
        try:
            out[cond] = float(val)
        except ValueError:
            raise LaughlabError(f"--effects: {val!r} is not a number") from None
        if not math.isfinite(out[cond]):
            raise LaughlabError("--effects must be finite")
        # past the scale's end every answer is cut to it: the report then read "laugh_energy +5 planted" over
        # answers all at 7 (a user-study review); study power refuses its --effect the same way
        from laughlab.study.design import scale_range

        lo, hi = scale_range(design)
        base = PLANTED_SPREAD["base"]
        if not lo <= base + out[cond] <= hi:
            raise LaughlabError(f"--effects {cond}={val} is impossible on this {lo:g}..{hi:g} scale: from the base "
                                f"rating {base:g} an effect must lie between {lo - base:+g} and {hi - base:+g}")
    return out
