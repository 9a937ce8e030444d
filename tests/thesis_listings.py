"""The thesis' pseudo-code, transcribed as plainly as Python allows: the literal reference for the plugins.

van Duijn (2014), "Real-time laughter on virtual characters": the mapping of 3.1.1,
the rise and fall of 3.1.2 (Eq. 3.2), listing 5.2 (live sound), listing 5.4
(laughing energy) and listing 5.5 (selecting animations).  One call of a
function body is one game-engine tick; every constant is per tick, as printed.
Nothing here is imported by laughlab: tests/test_thesis_listings.py runs these
tick by tick at 60 Hz beside the plugins and compares them step by step.

Where the printed text cannot run as it stands, the change is marked
``# READING:`` with the reason.
"""
from __future__ import annotations


def mapping_3_1_1(amplitudes, minAmp, maxAmp):
    """Section 3.1.1: map each amplitude to [0, 1] with the minimum and maximum so far."""
    out = []
    for amp in amplitudes:                               # for every timestep:
        # amp = getAmplitude(sound) #using the RMS amplitude
        if amp > maxAmp: maxAmp = amp                    # noqa: E701
        if amp < minAmp: minAmp = amp                    # noqa: E701
        motionSignal = (amp - minAmp) / (maxAmp - minAmp)
        out.append(motionSignal)
    return out


def rise_fall_3_2(signal, rise, fall, dt=1.0):
    """Eq. 3.2: finalMCS = min(MCS, prev + rise*dt) if MCS > prev else max(MCS, prev - fall*dt)."""
    out, prevMCS = [], 0.0  # READING: the thesis does not say where prevMCS starts; 0 (silence)
    for MCS in signal:
        if MCS > prevMCS:
            finalMCS = min(MCS, prevMCS + rise * dt)
        else:
            finalMCS = max(MCS, prevMCS - fall * dt)
        out.append(finalMCS)
        prevMCS = finalMCS
    return out


def listing_5_2(amplitudes, minAmp, maxAmp):
    """Listing 5.2 (line order restored as docs/papers.md explains): the motion control signal."""
    out = []
    previousMotionSignal = 0.0  # READING: not initialised in the listing; 0 (silence)
    for amplitude in amplitudes:                         # for every timestep:
        # extract the amplitude from the sound using PortAudio
        # amplitude = getAmplitude(microphoneStream)
        # use maximum and minimum amplitude so far to map the amplitude to the range [0,1]
        if amplitude > maxAmp: maxAmp = amplitude        # noqa: E701
        if amplitude < minAmp: minAmp = amplitude        # noqa: E701
        motionSignal = (amplitude - minAmp) / (maxAmp - minAmp)
        # decrease maxAmp and increase minAmp by a fixed amount to handle changes in volume
        fallof = 0.001
        maxAmp -= fallof
        minAmp += fallof
        # make sure the motion control signal can not rise or fall faster than specified
        ampRise, ampFall = 0.4, 0.2
        if motionSignal > previousMotionSignal:
            motionSignal = min(motionSignal, previousMotionSignal + ampRise)
        else:
            motionSignal = max(motionSignal, previousMotionSignal - ampFall)
        # update previous motion control signal
        previousMotionSignal = motionSignal
        # tweak the motion control signal for better results
        motionSignal = pow(motionSignal, 2)
        out.append(motionSignal)
    return out


class Action:
    """Listing 5.5's class, as printed."""

    # constructor
    def __init__(self, name="", length=0, energy=0):
        self.name = name
        self.length = length
        self.energy = energy
        self.active = False
        self.inactive_tics = 10000
        self.frame = 0.0   # READING: Blender keeps the action's frame; getActionFrame(act) reads it


def animation_actions():
    """The 11 actions of listing 5.5 (lengths in frames, energies as printed)."""
    return [Action("lean_front1", 22, energy=5),
            Action("lean_front2", 42, energy=10),
            Action("lean_back1", 22, energy=5),
            Action("lean_back2", 36, energy=10),
            Action("clap_hands", 46, energy=15),
            Action("hands_on_belly", 73, energy=15),
            Action("point1", 69, energy=20),
            Action("point2", 78, energy=20),
            Action("slap_leg", 80, energy=25),
            Action("stop_it", 79, energy=30),
            Action("rofl", 117, energy=40)]


class Blender:
    """What listing 5.5 asks of Blender's game engine, recorded per tick.

    READING: an action's frame advances by ``speed * action_fps / tick_hz`` per
    tick (the thesis states no rate: laughlab reads the clips as 24 fps actions
    in a 60 Hz game loop), and an action has finished when its frame reaches its
    length (``getActionFrame(act) == act.length`` cannot be met exactly by a
    frame that advances by fractions).
    """

    def __init__(self, rng, action_fps=24.0, tick_hz=60.0):
        self.rng, self.step = rng, action_fps / tick_hz
        self.events = []   # (tick, "start"/"stop", name)
        self.tick = 0

    def getActionFrame(self, act):
        return min(act.frame, act.length)

    def stopAction(self, act):
        self.events.append((self.tick, "stop", act.name))

    def playAction(self, act, blendin, speed):
        act.frame, act.speed = 0.0, speed
        self.events.append((self.tick, "start", act.name))

    def advance(self, actions):
        for act in actions:
            if act.active:
                act.frame += act.speed * self.step


def listings_5_4_and_5_5(mcs, rng, fixedDecreasingFactor, maxLaughingEnergy, overruleThreshold,
                         minInactiveTics, dt=1.0):
    """Listings 5.4 and 5.5, one tick per MCS value; returns (laughing energy per tick, Blender's events).

    ``rng`` is a numpy Generator: ``random.shuffle`` and ``random.uniform`` draw
    from it in the listing's order, so the plugin with the same generator makes
    the same draws.  ``dt`` is one tick (5.4 line 9 adds ``motionSignal * dt``
    and 5.5 subtracts ``act.energy * dt`` in the same unit).
    """
    blender = Blender(rng)
    animationActions = animation_actions()
    idle = Action("idle", 0, energy=0)   # READING: "an idle animation is playing as soon as no laughter
    activeAnimation = idle                # animation is playing" (5.5): energy 0 when none plays
    lastPlayedAction = None
    laughingEnergy = 0.0
    energies = []
    for tick, motionSignal in enumerate(mcs):
        blender.tick = tick
        # ---- listing 5.4 ----
        # decrease laughing energy with a fixed amount.
        laughingEnergy -= fixedDecreasingFactor
        # cap the laughing energy if it exceeds its maximum
        laughingEnergy = min(maxLaughingEnergy, laughingEnergy)
        # increase laughing energy with the motion control signal
        laughingEnergy += motionSignal * dt
        # ---- listing 5.5 ----
        ########### ANIMATION SELECTION ##########
        rng.shuffle(animationActions)                   # random.shuffle(animationActions)
        bestAction = None
        for act in animationActions:
            # activate an animation if it meets the requirements
            if (laughingEnergy > act.energy and not act.active and
                    act.energy > activeAnimation.energy * overruleThreshold and
                    act.inactive_tics > minInactiveTics):
                # if there is more than one candidate action, pick the one with the highest energy
                if (bestAction is None or act.energy > bestAction.energy):
                    bestAction = act
            if act.active:
                # deactivate the action if it has finished
                if blender.getActionFrame(act) >= act.length:   # READING: == on a fractional frame, see Blender
                    act.active = False
                    blender.stopAction(act)
                    activeAnimation = idle   # READING: not printed; the idle animation takes over (5.5)
                else:  # decrease the laughing_energy with the energy of the current animation
                    laughingEnergy -= act.energy * dt
                # set the number of inactive tics to 0 if the action is active...
                act.inactive_tics = 0
            else:
                # increase the number of tics this action has been inactive
                act.inactive_tics += 1
        if bestAction is not None:
            # deactivate the last action
            if lastPlayedAction is not None and lastPlayedAction.active:  # READING: stopping a finished
                lastPlayedAction.active = False                           # action changes nothing
                blender.stopAction(lastPlayedAction)
            # play the animation with a random speed to introduce some variation
            # READING: the listing passes act (the loop's last action); bestAction is meant
            blender.playAction(bestAction, blendin=10, speed=rng.uniform(0.9, 1.4))
            bestAction.active = True
            lastPlayedAction = bestAction
            activeAnimation = bestAction
        energies.append(laughingEnergy)
        blender.advance(animationActions)   # the engine plays the actions' next frame
    return energies, blender.events


# ---- listing 5.3 (Smoother) and Eqs. 3.3-3.4 ----

class Smoother:
    """Listing 5.3: smooth and re-scale the motion control signal (as printed)."""

    # constructor with default parameters
    def __init__(self, rise=0.5, fall=0.2, minE=0.0, maxE=1.0):
        self.rise = rise
        self.fall = fall
        # minE and maxE are used to re-scale the motion control signal
        # as shown in the smooth() function below
        self.minE = minE
        self.maxE = maxE
        self.range = maxE - minE
        # the output signal
        self.e = 0

    # input: original motion control signal
    # output: motion control signal subject to a rise and fall parameter & scaled to [min, max]
    def smooth(self, motionSignal):
        # allow the signal to rise and fall only by a set amount
        if motionSignal > self.e:
            self.e = min(motionSignal, self.e + self.rise)
        else:
            self.e = max(motionSignal, self.e - self.fall)
        scaled = self.e
        # re-scale the motion control signal so that:
        # every original value smaller than minE will be mapped to 0
        if self.e < self.minE:
            scaled = 0.0
        # every original value greater than maxE will be mapped to 1
        elif self.e > self.maxE:
            scaled = 1.0
        # and every original value that lays in between minE and maxE
        # gets scaled accordingly
        else:
            scaled = (self.e - self.minE) / self.range
        return scaled


def smoothers_5_3(mcs):
    """The four smoothers of 5.3 over an MCS trace, with chest and belly influence (Eqs. 3.3, 3.4)."""
    # the smoothers that return a smoother and re-scaled vesion of the sound curve
    jawSmoother = Smoother(rise=0.03, fall=0.01, minE=0.0, maxE=0.8)
    smileSmoother = Smoother(rise=0.03, fall=0.001, minE=0.0, maxE=0.3)
    chestSmoother = Smoother(rise=0.2, fall=0.1, minE=0.0, maxE=1.0)
    bellySmoother = Smoother(rise=0.1, fall=0.05, minE=0.0, maxE=1.0)
    out = []
    for MCS in mcs:
        chestInfluence = 1 - chestSmoother.smooth(MCS)   # Eq. 3.3 on the smoothed MCS (3.2.2)
        bellyInfluence = bellySmoother.smooth(MCS)       # Eq. 3.4
        out.append({"jaw": jawSmoother.smooth(MCS), "smile": smileSmoother.smooth(MCS),
                    "chest": chestInfluence, "belly": bellyInfluence})
    return out
