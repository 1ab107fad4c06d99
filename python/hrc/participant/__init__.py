"""The participant model (docs/participant-model.md): the motor law (motor), the hand that
follows it (hand), the plans of a reach and a carry (plans), MTM's element times (elements),
the hand samples and their recordings (sample, recording) and the fit of a person's parameters
from recorded trials (fit). The scripted participant (services/human_input) drives it; the CLI
(`hrc fit`, `hrc bench participant`) uses it without starting a service."""
