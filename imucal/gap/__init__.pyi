from .diagnosis import FORMAT_VERSION, DiagnosisSettings, diagnose
