from .diagnosis import diagnose
from .scoring import FORMAT_VERSION, DiagnosisSettings, scored_diagnosis, verdict_of
